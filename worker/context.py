"""Per-process database access for the worker: one engine per OS process (never shared across fork)."""

from __future__ import annotations

import os

from sqlalchemy.orm import Session, sessionmaker

from service.settings import get_settings
from service.store.db import make_engine, make_sessionmaker

_sessions: dict[int, sessionmaker[Session]] = {}


def sessions() -> sessionmaker[Session]:
    """The session factory of this process, created on first use after any fork (prefork pool children)."""
    pid = os.getpid()
    if pid not in _sessions:
        _sessions.clear()
        _sessions[pid] = make_sessionmaker(make_engine(get_settings(), pre_ping=True))
    return _sessions[pid]
