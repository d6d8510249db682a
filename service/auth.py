"""API-key authentication: ``Authorization: Bearer mirl_<key id>_<secret>``, secrets stored as SHA-256."""

from __future__ import annotations

import hashlib
import hmac
import secrets
from typing import Annotated

from fastapi import Depends, Security
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import select
from sqlalchemy.orm import Session

from service.deps import SessionDep
from service.models.labs import ApiKey, Lab
from service.problems import Unauthorized

KEY_PREFIX = "mirl"
bearer = HTTPBearer(auto_error=False, description="An API key from `metairl keys create --lab NAME`.")


def new_key_parts() -> tuple[str, str]:
    """A fresh (key id, secret): the id is looked up, the secret (256 bits) is only ever stored hashed."""
    return secrets.token_hex(8), secrets.token_urlsafe(32)


def format_key(key_id: str, secret: str) -> str:
    """The key as given to the user."""
    return f"{KEY_PREFIX}_{key_id}_{secret}"


def hash_secret(secret: str) -> str:
    """SHA-256 hex of a key's secret (a high-entropy secret needs no slow hash)."""
    return hashlib.sha256(secret.encode()).hexdigest()


def lab_for_key(session: Session, key: str) -> Lab | None:
    """The lab owning API key `key`, or None if the key is malformed, unknown or revoked."""
    prefix, _, rest = key.partition("_")
    key_id, _, secret = rest.partition("_")
    if prefix != KEY_PREFIX or not key_id or not secret:
        return None
    row = session.execute(
        select(ApiKey, Lab).join(Lab, Lab.id == ApiKey.lab_id).where(ApiKey.id == key_id)
    ).first()
    if row is None or row.ApiKey.revoked_at is not None:
        return None
    if not hmac.compare_digest(row.ApiKey.secret_sha256, hash_secret(secret)):
        return None
    return row.Lab


def current_lab(
    session: SessionDep, credentials: Annotated[HTTPAuthorizationCredentials | None, Security(bearer)]
) -> Lab:
    """The lab making this request; 401 problem without a valid bearer key."""
    challenge = {"WWW-Authenticate": "Bearer"}
    if credentials is None:
        raise Unauthorized("Send 'Authorization: Bearer <api key>'.", headers=challenge)
    lab = lab_for_key(session, credentials.credentials)
    if lab is None:
        raise Unauthorized("The API key is unknown or revoked.", headers=challenge)
    return lab


LabDep = Annotated[Lab, Depends(current_lab)]
