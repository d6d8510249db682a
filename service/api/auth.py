"""API-key authentication: ``Authorization: Bearer mirl_<key id>_<secret>``, secrets stored as SHA-256.

With ``METAIRL_API_KEY_CACHE_S`` > 0 a key the database has confirmed is remembered in-process that many
seconds, so a request with a recently seen key costs no database round trip, and a revoked key is refused
within that time. The default 0 asks the database every time: the next request after a revocation gets 401.
Unknown or revoked keys are never remembered.
"""

from __future__ import annotations

import hashlib
import hmac
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Request, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import select
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session

from service.problems import Unauthorized
from service.store.keys import LAST_USED_RESOLUTION_S, hash_secret, split_key, touch_key
from service.store.models.base import utcnow
from service.store.models.labs import ApiKey, Lab

log = logging.getLogger(__name__)

bearer = HTTPBearer(auto_error=False, description="An API key from `metairl keys create --lab NAME`.")


@dataclass(frozen=True)
class Caller:
    """The lab making a request (routes read only its id), safe to keep between requests."""

    id: str
    name: str


class KeyCache:
    """Keys the database confirmed recently: the key's SHA-256 → (its lab, when to ask again).

    Thread-safe (sync routes run in a thread pool); holds at most `max_entries`, dropping the oldest.
    """

    def __init__(
        self, ttl_s: float, *, max_entries: int = 10_000, clock: Callable[[], float] = time.monotonic
    ) -> None:
        self.ttl_s = ttl_s
        self.max_entries = max_entries
        self._clock = clock
        self._entries: dict[bytes, tuple[Caller, float]] = {}
        self._lock = threading.Lock()

    @staticmethod
    def _digest(key: str) -> bytes:
        return hashlib.sha256(key.encode()).digest()

    def get(self, key: str) -> Caller | None:
        """The lab of `key` if it was confirmed less than `ttl_s` ago."""
        if self.ttl_s <= 0:
            return None
        entry = self._entries.get(self._digest(key))
        if entry is None or entry[1] <= self._clock():
            return None
        return entry[0]

    def put(self, key: str, caller: Caller) -> None:
        """Remember that `key` belongs to `caller` for the next `ttl_s` seconds."""
        if self.ttl_s <= 0:
            return
        with self._lock:
            if len(self._entries) >= self.max_entries:
                now = self._clock()
                self._entries = {d: e for d, e in self._entries.items() if e[1] > now}
                while len(self._entries) >= self.max_entries:
                    del self._entries[next(iter(self._entries))]
            self._entries[self._digest(key)] = (caller, self._clock() + self.ttl_s)


def key_and_lab(session: Session, key: str) -> tuple[ApiKey, Lab] | None:
    """The key row and the lab owning API key `key`, or None if the key is malformed, unknown or revoked."""
    parts = split_key(key)
    if parts is None:
        return None
    key_id, secret = parts
    row = session.execute(
        select(ApiKey, Lab).join(Lab, Lab.id == ApiKey.lab_id).where(ApiKey.id == key_id)
    ).first()
    if row is None or row.ApiKey.revoked_at is not None:
        return None
    if not hmac.compare_digest(row.ApiKey.secret_sha256, hash_secret(secret)):
        return None
    return row.ApiKey, row.Lab


def lab_for_key(session: Session, key: str) -> Lab | None:
    """The lab owning API key `key`, or None if the key is malformed, unknown or revoked."""
    found = key_and_lab(session, key)
    return None if found is None else found[1]


def current_lab(
    request: Request, credentials: Annotated[HTTPAuthorizationCredentials | None, Security(bearer)]
) -> Caller:
    """The lab making this request; 401 problem without a valid bearer key.

    A key confirmed in the last ``METAIRL_API_KEY_CACHE_S`` seconds is answered from the process's
    `KeyCache`. Otherwise the key is checked in a short autocommit session of its own, which also notes the
    key's use (`last_used_at`, at most once a minute): the request's own session and unit of work stay the
    route's, and the check holds no connection while the route runs."""
    challenge = {"WWW-Authenticate": "Bearer"}
    if credentials is None:
        raise Unauthorized("Send 'Authorization: Bearer <api key>'.", headers=challenge)
    cache: KeyCache | None = getattr(request.app.state, "key_cache", None)
    caller = cache.get(credentials.credentials) if cache is not None else None
    if caller is not None:
        return caller
    with request.app.state.key_sessionmaker() as own:
        found = key_and_lab(own, credentials.credentials)
        if found is None:
            raise Unauthorized("The API key is unknown or revoked.", headers=challenge)
        key, lab = found
        last = key.last_used_at
        if last is None or (utcnow() - last).total_seconds() >= LAST_USED_RESOLUTION_S:
            try:
                touch_key(own, key.id)
                own.commit()
            except SQLAlchemyError:
                own.rollback()
                log.warning("could not record the use of API key %s", key.id, exc_info=True)
        caller = Caller(id=lab.id, name=lab.name)
    if cache is not None:
        cache.put(credentials.credentials, caller)
    return caller


LabDep = Annotated[Caller, Depends(current_lab)]
