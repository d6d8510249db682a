"""Labs and their API keys: ``mirl_<key id>_<secret>``, the secret stored only as its SHA-256."""

from __future__ import annotations

import hashlib
import hmac
import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, TypeAlias

from sqlalchemy import ColumnElement, Select, Update, bindparam, or_, select, update
from sqlalchemy.orm import InstrumentedAttribute, Session

from service.store.ids import new_id
from service.store.models.base import utcnow
from service.store.models.labs import ApiKey, Lab

KEY_PREFIX = "mirl"
LAST_USED_RESOLUTION_S = 60
"""`last_used_at` is written at most once a minute per key, so reads do not each cost a write."""
KeyedQuery: TypeAlias = Select[*tuple[Any, ...]]
"""A `key_select`, with whatever columns a route adds to it."""


def new_key_parts() -> tuple[str, str]:
    """A fresh (key id, secret): the id is looked up, the secret (256 bits) is only ever stored hashed."""
    return secrets.token_hex(8), secrets.token_urlsafe(32)


def format_key(key_id: str, secret: str) -> str:
    """The key as given to the user."""
    return f"{KEY_PREFIX}_{key_id}_{secret}"


def hash_secret(secret: str) -> str:
    """SHA-256 hex of a key's secret (a high-entropy secret needs no slow hash)."""
    return hashlib.sha256(secret.encode()).hexdigest()


def add_key(session: Session, lab_name: str) -> str:
    """Add lab `lab_name` if new and a new key for it (flushed, not committed); returns the key, which is
    shown only once."""
    lab = session.execute(select(Lab).where(Lab.name == lab_name)).scalar_one_or_none()
    if lab is None:
        lab = Lab(id=new_id("lab"), name=lab_name)
        session.add(lab)
        session.flush()
    key_id, secret = new_key_parts()
    session.add(ApiKey(id=key_id, lab_id=lab.id, secret_sha256=hash_secret(secret)))
    session.flush()
    return format_key(key_id, secret)


def split_key(key: str) -> tuple[str, str] | None:
    """(key id, secret) of a well-formed key ``mirl_<id>_<secret>``, else None."""
    prefix, _, rest = key.partition("_")
    key_id, _, secret = rest.partition("_")
    if prefix != KEY_PREFIX or not key_id or not secret:
        return None
    return key_id, secret


def key_is_valid(session: Session, key: str) -> bool:
    """Whether `key` is known, not revoked, and its secret matches."""
    parts = split_key(key)
    if parts is None:
        return False
    row = session.get(ApiKey, parts[0])
    return row is not None and secret_matches(row.secret_sha256, row.revoked_at, parts[1])


def secret_matches(secret_sha256: str, revoked_at: datetime | None, secret: str) -> bool:
    """Whether a stored key (its secret's SHA-256 and revocation time) is live and `secret` is its secret
    (compared in constant time)."""
    return revoked_at is None and hmac.compare_digest(secret_sha256, hash_secret(secret))


def use_is_stale(last_used_at: datetime | None, *, now: datetime | None = None) -> bool:
    """Whether a key's recorded use is missing or at least `LAST_USED_RESOLUTION_S` old (so worth a write)."""
    return (
        last_used_at is None or ((now or utcnow()) - last_used_at).total_seconds() >= LAST_USED_RESOLUTION_S
    )


def touch_statement(key_id: str, *, now: datetime | None = None) -> Update:
    """The UPDATE setting the key's `last_used_at` to now unless it was set less than `LAST_USED_RESOLUTION_S`
    ago (so that concurrent requests write it once)."""
    now = now or utcnow()
    return (
        update(ApiKey)
        .where(
            ApiKey.id == key_id,
            or_(
                ApiKey.last_used_at.is_(None),
                ApiKey.last_used_at < now - timedelta(seconds=LAST_USED_RESOLUTION_S),
            ),
        )
        .values(last_used_at=now)
        .execution_options(synchronize_session=False)
    )


def touch_key(session: Session, key_id: str, *, now: datetime | None = None) -> None:
    """Set the key's `last_used_at` to now unless it was set less than `LAST_USED_RESOLUTION_S` ago."""
    session.execute(touch_statement(key_id, now=now))


def key_select() -> KeyedQuery:
    """The key bound as ``:key_id`` and its lab, as one row of labelled columns (``key_secret_sha256``,
    ``key_revoked_at``, ``key_last_used_at``, ``key_lab_id``, ``key_lab_name``); none if there is no such key.

    A route that checks the key and reads a resource in one statement adds the resource to it, outer-joined on
    `in_key_lab`, so the row says both whether the key is good and the resource, if the key's lab has it. The
    statement is built once (its parameters bound at execution): building it costs more than running it.
    """
    return (
        select(
            ApiKey.secret_sha256.label("key_secret_sha256"),
            ApiKey.revoked_at.label("key_revoked_at"),
            ApiKey.last_used_at.label("key_last_used_at"),
            ApiKey.lab_id.label("key_lab_id"),
            Lab.name.label("key_lab_name"),
        )
        .select_from(ApiKey)
        .join(Lab, Lab.id == ApiKey.lab_id)
        .where(ApiKey.id == bindparam("key_id"))
    )


def in_key_lab(lab_id: InstrumentedAttribute[str]) -> ColumnElement[bool]:
    """The join condition that a resource (its `lab_id` column) belongs to the lab of `key_select`'s key."""
    return lab_id == ApiKey.lab_id


@dataclass(frozen=True)
class KeyInfo:
    """One key as `metairl keys list` shows it (never its secret, which is not stored)."""

    id: str
    lab: str
    created_at: datetime
    last_used_at: datetime | None
    revoked_at: datetime | None


def list_keys(session: Session, *, lab_name: str | None = None) -> list[KeyInfo]:
    """Every key (of lab `lab_name` if given), oldest first."""
    query = select(ApiKey, Lab.name).join(Lab, Lab.id == ApiKey.lab_id).order_by(ApiKey.created_at, ApiKey.id)
    if lab_name is not None:
        query = query.where(Lab.name == lab_name)
    return [
        KeyInfo(key.id, name, key.created_at, key.last_used_at, key.revoked_at)
        for key, name in session.execute(query)
    ]


def revoke_key(session: Session, key_id: str) -> ApiKey | None:
    """Revoke key `key_id` (a full key is accepted too, only with its own secret: a mistyped one names no
    key); None if there is no such key. Flushed, not committed; revoking a revoked key keeps its first
    revocation time."""
    parts = split_key(key_id)
    row = session.get(ApiKey, parts[0] if parts else key_id)
    if row is not None and parts and not hmac.compare_digest(row.secret_sha256, hash_secret(parts[1])):
        return None
    if row is not None and row.revoked_at is None:
        row.revoked_at = utcnow()
        session.flush()
    return row
