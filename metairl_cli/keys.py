"""``metairl keys create|list|revoke``: new keys (printed once), the keys there are, and revoking one.

`list` prints one key per line, tab-separated: id, lab, created, last used (``never``), revoked (``-`` while
active); times are ISO 8601 UTC to the second. The secret of a key is never stored, so it is never listed.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime

from sqlalchemy.orm import Session

from service.settings import get_settings
from service.store.db import make_engine, migrate
from service.store.keys import KeyInfo, add_key, list_keys, revoke_key


def create_key(session: Session, lab_name: str) -> str:
    """Create lab `lab_name` if new and a new key for it; commits and returns the key (shown only once)."""
    key = add_key(session, lab_name)
    session.commit()
    return key


def create_key_command(*, lab: str) -> int:
    """Migrate the configured database, create the key and print it alone on the last line; exit code."""
    if not lab.strip():
        print("error: --lab must not be empty")
        return 2
    engine = make_engine(get_settings())
    try:
        migrate(engine)
        with Session(engine) as session:
            key = create_key(session, lab.strip())
    finally:
        engine.dispose()
    print(f"Created an API key for lab {lab.strip()!r}. Send it as 'Authorization: Bearer <key>':")
    print(key)
    return 0


@contextmanager
def migrated_session() -> Iterator[Session]:
    """A session on the configured database, migrated first (the CLI opens it, so the CLI commits)."""
    engine = make_engine(get_settings())
    try:
        migrate(engine)
        with Session(engine) as session:
            yield session
    finally:
        engine.dispose()


def _when(moment: datetime | None, empty: str) -> str:
    """ISO 8601 UTC to the second, or `empty`."""
    return empty if moment is None else moment.strftime("%Y-%m-%dT%H:%M:%SZ")


def key_line(info: KeyInfo) -> str:
    """One line of `metairl keys list`."""
    return "\t".join(
        [
            info.id,
            info.lab,
            _when(info.created_at, "-"),
            _when(info.last_used_at, "never"),
            _when(info.revoked_at, "-"),
        ]
    )


def list_keys_command(*, lab: str | None) -> int:
    """Print every key (of `lab` if given), one per line, oldest first; exit code 1 for a lab without keys."""
    with migrated_session() as session:
        keys = list_keys(session, lab_name=None if lab is None else lab.strip())
    if not keys and lab is not None:  # say so, rather than print nothing for a misspelt lab
        print(f"error: lab {lab.strip()!r} has no API keys (see 'metairl keys list' for every lab's)")
        return 1
    for info in keys:
        print(key_line(info))
    return 0


def revoke_key_command(*, key_id: str) -> int:
    """Revoke a key by id (or the full key); 0 if it is now revoked, 1 if there is no such key."""
    with migrated_session() as session:
        row = revoke_key(session, key_id.strip())
        session.commit()
        if row is None:
            print(f"error: no API key with id {key_id!r} (see 'metairl keys list')")
            return 1
        print(f"API key {row.id} revoked at {_when(row.revoked_at, '-')}; requests with it now get 401.")
    return 0
