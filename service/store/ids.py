"""Opaque resource ids with a type prefix (``mdp_…``, ``task_…``): the primary keys and the API ids."""

from __future__ import annotations

import secrets


def new_id(prefix: str) -> str:
    """A fresh id ``<prefix>_<22 url-safe random characters>`` (about 128 bits of entropy)."""
    return f"{prefix}_{secrets.token_urlsafe(16)}"
