"""API-key authentication: ``Authorization: Bearer mirl_<key id>_<secret>``, secrets stored as SHA-256.

With ``METAIRL_API_KEY_CACHE_S`` > 0 a key the database has confirmed is remembered in-process that many
seconds, so a request with a recently seen key costs no database round trip, and a revoked key is refused
within that time. The default 0 asks the database every time: the next request after a revocation gets 401.
Unknown or revoked keys are never remembered. The hot read routes check the key in the statement that reads
their resource (`authorised_row`, on the async engine), so they refuse a revoked key at once either way.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any

from fastapi import Depends, Request, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import Row, select
from sqlalchemy.exc import SQLAlchemyError
from sqlalchemy.orm import Session

from service.api.async_db import connection
from service.problems import Unauthorized
from service.store.keys import (
    KeyedQuery,
    secret_matches,
    split_key,
    touch_key,
    touch_statement,
    use_is_stale,
)
from service.store.models.labs import ApiKey, Lab

log = logging.getLogger(__name__)

bearer = HTTPBearer(auto_error=False, description="An API key from `metairl keys create --lab NAME`.")
BearerDep = Annotated[HTTPAuthorizationCredentials | None, Security(bearer)]
"""The request's bearer credentials, if any (documents the scheme in OpenAPI; checking them is the route's)."""
CHALLENGE = {"WWW-Authenticate": "Bearer"}
NO_KEY = "Send 'Authorization: Bearer <api key>'."
BAD_KEY = "The API key is unknown or revoked."


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
    if row is None or not secret_matches(row.ApiKey.secret_sha256, row.ApiKey.revoked_at, secret):
        return None
    return row.ApiKey, row.Lab


def lab_for_key(session: Session, key: str) -> Lab | None:
    """The lab owning API key `key`, or None if the key is malformed, unknown or revoked."""
    found = key_and_lab(session, key)
    return None if found is None else found[1]


def current_lab(request: Request, credentials: BearerDep) -> Caller:
    """The lab making this request; 401 problem without a valid bearer key.

    A key confirmed in the last ``METAIRL_API_KEY_CACHE_S`` seconds is answered from the process's
    `KeyCache`. Otherwise the key is checked in a short autocommit session of its own, which also notes the
    key's use (`last_used_at`, at most once a minute): the request's own session and unit of work stay the
    route's, and the check holds no connection while the route runs."""
    if credentials is None:
        raise Unauthorized(NO_KEY, headers=CHALLENGE)
    cache: KeyCache | None = getattr(request.app.state, "key_cache", None)
    caller = cache.get(credentials.credentials) if cache is not None else None
    if caller is not None:
        return caller
    with request.app.state.key_sessionmaker() as own:
        found = key_and_lab(own, credentials.credentials)
        if found is None:
            raise Unauthorized(BAD_KEY, headers=CHALLENGE)
        key, lab = found
        if use_is_stale(key.last_used_at):
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


async def authorised_row(
    request: Request, credentials: HTTPAuthorizationCredentials | None, query: KeyedQuery, **params: str
) -> Row[Any]:
    """The async counterpart of `current_lab` for the hot read routes: ONE statement checks the bearer key and
    reads what the route needs, on the process's async engine (`service.api.async_db`).

    `query` is a `key_select` with the route's columns added (outer-joined in the key's lab, so they are NULL
    when the lab has no such resource), run with the key's id and `params`; the row returned holds them and
    ``key_lab_id``, the caller's lab. The answers are `current_lab`'s: 401 with the same problem and challenge
    for a missing, malformed, unknown, revoked or wrong key. The key's use is recorded as there (a second,
    conditional UPDATE at most once a minute). The database is asked on every request, cache or not, since the
    key's row comes with the read anyway: a revocation is refused at once. A confirmed key is put in the
    `KeyCache` for the sync routes.
    """
    if credentials is None:
        raise Unauthorized(NO_KEY, headers=CHALLENGE)
    parts = split_key(credentials.credentials)
    if parts is None:
        raise Unauthorized(BAD_KEY, headers=CHALLENGE)
    key_id, secret = parts
    async with connection(request) as db:
        row = (await db.execute(query, {"key_id": key_id, **params})).first()
        if row is None or not secret_matches(row.key_secret_sha256, row.key_revoked_at, secret):
            raise Unauthorized(BAD_KEY, headers=CHALLENGE)
        if use_is_stale(row.key_last_used_at):
            try:
                await db.execute(touch_statement(key_id))
            except SQLAlchemyError:
                log.warning("could not record the use of API key %s", key_id, exc_info=True)
    cache: KeyCache | None = getattr(request.app.state, "key_cache", None)
    if cache is not None:
        cache.put(credentials.credentials, Caller(id=row.key_lab_id, name=row.key_lab_name))
    return row


LabDep = Annotated[Caller, Depends(current_lab)]
