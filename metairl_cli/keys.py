"""``metairl keys create|list|revoke``: new keys (printed once), the keys there are, and revoking one.

`list` prints one key per line, tab-separated: id, lab, created, last used (``never``), revoked (``-`` while
active); times are ISO 8601 UTC to the second. The secret of a key is never stored, so it is never listed.
`create` migrates (and on SQLite creates) the database; `list` and `revoke` refuse one without the schema, so a
mistyped ``METAIRL_DATA_DIR`` says so instead of creating an empty database. Errors go to stderr.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime

from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session

from service.settings import Settings, get_settings
from service.store.db import NewerSchema, database_name, database_state, make_engine, migrate
from service.store.keys import KeyInfo, add_key, list_keys, revoke_key


def create_key(session: Session, lab_name: str) -> str:
    """Create lab `lab_name` if new and a new key for it; commits and returns the key (shown only once)."""
    key = add_key(session, lab_name)
    session.commit()
    return key


def create_key_command(*, lab: str) -> int:
    """Migrate the configured database, create the key and print it alone on the last line; exit code (1 for a
    database that newer code migrated)."""
    if not lab.strip():
        print("error: --lab must not be empty", file=sys.stderr)
        return 2
    engine = make_engine(get_settings())
    try:
        migrate(engine)
        with Session(engine) as session:
            key = create_key(session, lab.strip())
    except NewerSchema as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    finally:
        engine.dispose()
    print(f"Created an API key for lab {lab.strip()!r}. Send it as 'Authorization: Bearer <key>':")
    print(key)
    return 0


class NoDatabase(Exception):
    """The configured database has no metairl schema, or one newer than this code's (the message says which)."""


def existing_database_problem(settings: Settings) -> str | None:
    """Why `list` and `revoke` cannot use the configured database (one line naming it), or None: it must exist
    with the schema; one at an older migration is fine (`migrated_session` upgrades it)."""
    name = database_name(settings)
    try:
        state = database_state(settings)
    except OperationalError as exc:
        reason = str(exc.orig or exc).strip().splitlines() or [type(exc).__name__]
        return f"cannot open the database at {name}: {reason[0]}"
    if state == "empty":
        return (
            f"no metairl database at {name} (never created, or never migrated); "
            "set METAIRL_DATA_DIR (or METAIRL_DATABASE_URL) to the service's"
        )
    if state == "ahead":
        return f"the database at {name} was migrated by a newer metairl; run this command with that version"
    return None


@contextmanager
def migrated_session() -> Iterator[Session]:
    """A session on the configured database, brought to the newest migration (the CLI opens it, so the CLI
    commits); `NoDatabase` rather than create a database that does not exist."""
    settings = get_settings()
    problem = existing_database_problem(settings)
    if problem is not None:
        raise NoDatabase(problem)
    engine = make_engine(settings)
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
    """Print every key (of `lab` if given), one per line, oldest first; exit code 1 for a lab without keys or
    no database."""
    try:
        with migrated_session() as session:
            keys = list_keys(session, lab_name=None if lab is None else lab.strip())
    except NoDatabase as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    if not keys and lab is not None:  # say so, rather than print nothing for a misspelt lab
        print(
            f"error: lab {lab.strip()!r} has no API keys (see 'metairl keys list' for every lab's)",
            file=sys.stderr,
        )
        return 1
    for info in keys:
        print(key_line(info))
    return 0


def revoke_key_command(*, key_id: str) -> int:
    """Revoke a key by id (or the full key); 0 if it is now revoked, 1 if there is no such key or no database."""
    try:
        with migrated_session() as session:
            row = revoke_key(session, key_id.strip())
            session.commit()
            if row is None:
                print(f"error: no API key with id {key_id!r} (see 'metairl keys list')", file=sys.stderr)
                return 1
            print(f"API key {row.id} revoked at {_when(row.revoked_at, '-')}; requests with it now get 401.")
    except NoDatabase as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0
