"""Engine, sessions and migrations for SQLite (default, a file in data_dir) and PostgreSQL."""

from __future__ import annotations

import contextlib
import fcntl
import re
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from sqlalchemy import URL, Connection, Engine, create_engine, event, inspect, make_url, text
from sqlalchemy.ext.asyncio import AsyncEngine, create_async_engine
from sqlalchemy.orm import Session, sessionmaker
from sqlalchemy.pool import NullPool

from service.settings import Settings

if TYPE_CHECKING:
    from alembic.config import Config

MIGRATIONS_DIR = Path(__file__).parent / "migrations"
SQLITE_BUSY_TIMEOUT_MS = 30_000
PG_MIGRATION_LOCK = 0x6D6574616972_6C
"""PostgreSQL advisory-lock key held while migrating (any constant shared by all processes)."""
_THREAD_LOCK = threading.Lock()
"""Alembic's `context` is process-global: one migration at a time per process."""


def make_engine(settings: Settings, *, pre_ping: bool = False) -> Engine:
    """An engine for the configured database (SQLite: WAL, foreign keys, busy timeout; PostgreSQL: a pool of
    `db_pool_size` connections recycled after `db_pool_recycle_s`, waited for at most `db_pool_timeout_s`).

    `pre_ping` tests each connection with a round trip when it is checked out: the worker (seconds between
    writes, on long-lived connections) asks for it; the API does not, because it would double the round trips
    of a short request. A connection that died anyway (the server restarted) fails its request with a 503
    problem (`service.problems`), and SQLAlchemy then drops every older pooled connection, so the next
    requests reconnect.
    """
    url = settings.resolved_database_url
    if url.startswith("sqlite"):
        database = url.split("///", 1)[1] if "///" in url else ""
        if database and database != ":memory:":
            Path(database).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(
            url, connect_args={"check_same_thread": False, "timeout": SQLITE_BUSY_TIMEOUT_MS / 1000}
        )
        event.listen(engine, "connect", _sqlite_pragmas)
        return engine
    return create_engine(
        url,
        pool_pre_ping=pre_ping,
        pool_size=settings.db_pool_size,
        max_overflow=settings.db_max_overflow,
        pool_recycle=settings.db_pool_recycle_s,
        pool_timeout=settings.db_pool_timeout_s,
    )


ASYNC_DRIVERS = {"sqlite": "sqlite+aiosqlite", "postgresql": "postgresql+asyncpg"}
"""The asyncio driver of each backend (`async_url`)."""


def async_url(url: str) -> URL:
    """The configured (sync) database URL with the backend's asyncio driver: ``postgresql[+psycopg]://…`` →
    ``postgresql+asyncpg://…``, ``sqlite:///…`` → ``sqlite+aiosqlite:///…``; host, credentials, database and
    options kept, except libpq's ``sslmode``, which asyncpg takes (with the same values) as ``ssl``."""
    parsed = make_url(url)
    backend = parsed.get_backend_name()
    query = dict(parsed.query)
    if backend == "postgresql" and "sslmode" in query:
        query["ssl"] = query.pop("sslmode")
    return parsed.set(drivername=ASYNC_DRIVERS[backend], query=query)


def make_async_engine(settings: Settings, *, pooled: bool = True) -> AsyncEngine:
    """An asyncio engine on the configured database (asyncpg or aiosqlite) whose connections commit each
    statement on their own (AUTOCOMMIT): the async reads are single statements, so they cost no BEGIN and
    ROLLBACK round trips.

    Pooled like `make_engine` (PostgreSQL: `db_pool_size` + `db_max_overflow`, recycled after
    `db_pool_recycle_s`, never pinged before use; SQLite: the same pragmas). A pool belongs to one event loop:
    `pooled=False` gives an engine that opens a connection per use, for a caller without a loop-long engine.
    """
    url = async_url(settings.resolved_database_url)
    sqlite = url.get_backend_name() == "sqlite"
    options: dict[str, Any] = {"isolation_level": "AUTOCOMMIT"}
    if not pooled:
        options["poolclass"] = NullPool
    elif not sqlite:
        options |= {
            "pool_size": settings.db_pool_size,
            "max_overflow": settings.db_max_overflow,
            "pool_recycle": settings.db_pool_recycle_s,
            "pool_timeout": settings.db_pool_timeout_s,
        }
    if sqlite:
        options["connect_args"] = {"timeout": SQLITE_BUSY_TIMEOUT_MS / 1000}
    engine = create_async_engine(url, **options)
    if sqlite:
        event.listen(engine.sync_engine, "connect", _sqlite_pragmas)
    return engine


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    """Per-connection SQLite settings: write-ahead log (readers never block the writer), foreign keys on,
    deleted content overwritten with zeros (a deleted demonstrator's data does not linger in free pages)."""
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute(f"PRAGMA busy_timeout={SQLITE_BUSY_TIMEOUT_MS}")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.execute("PRAGMA secure_delete=ON")
    cursor.close()


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    """Sessions whose objects stay readable after commit (routes serialise them after committing)."""
    return sessionmaker(engine, expire_on_commit=False)


def alembic_config(connection: Connection) -> Config:
    """Alembic's configuration built in code (no alembic.ini), running on `connection`."""
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS_DIR).replace("%", "%%"))
    config.attributes["connection"] = connection
    return config


class NewerSchema(RuntimeError):
    """The database is stamped with a migration this code does not know: newer code migrated it, and this
    code must neither downgrade it nor write to a schema it does not know."""


def migrate(engine: Engine) -> None:
    """Upgrade the database to the newest revision; safe when several processes (or threads) start at once;
    `NewerSchema` (naming the database) for one that newer code migrated.

    A database already at the newest revision is left alone without importing Alembic (an API process then
    never loads it: about 30 MB per process). The check runs under the migration lock too: on a new SQLite
    file, connections opened at once race to switch it to WAL, and one of them can be refused as locked.
    """
    with _THREAD_LOCK, _migration_lock(engine):
        state = schema_state(engine)
        if state == "current":
            return
        if state == "ahead":
            raise NewerSchema(
                f"the database at {url_name(engine.url)} was migrated by a newer metairl; "
                "run this command with that version"
            )
        from alembic import command

        with engine.connect() as connection:
            if engine.dialect.name == "postgresql":
                connection.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": PG_MIGRATION_LOCK})
            command.upgrade(alembic_config(connection), "head")
            connection.commit()


_REVISION = re.compile(r"""^(down_revision|revision)\s*(?::[^=]+)?=\s*(?:["']([^"']+)["']|None)""", re.M)

SchemaState = Literal["current", "empty", "behind", "ahead"]
"""Where a database stands against this code's migrations (`schema_state`)."""


def _revision_graph() -> tuple[set[str], set[str]]:
    """Every revision id in migrations/versions, and those some revision names as its parent (no Alembic)."""
    revisions: set[str] = set()
    parents: set[str] = set()
    for path in (MIGRATIONS_DIR / "versions").glob("*.py"):
        for name, value in _REVISION.findall(path.read_text(encoding="utf-8")):
            if value:
                (revisions if name == "revision" else parents).add(value)
    return revisions, parents


def head_revision() -> str | None:
    """The newest migration's revision id, read from the files in migrations/versions (no Alembic import);
    None unless there is exactly one head."""
    revisions, parents = _revision_graph()
    heads = revisions - parents
    return heads.pop() if len(heads) == 1 else None


def schema_state(engine: Engine) -> SchemaState:
    """Whether the database is at this code's newest revision (``current``), has no schema (``empty``), is
    stamped with an older revision this code can upgrade (``behind``) or with one it does not know, written
    by newer code (``ahead``); one query, no Alembic import."""
    with engine.connect() as connection:
        if not inspect(connection).has_table("alembic_version"):
            return "empty"
        stamped = set(connection.execute(text("SELECT version_num FROM alembic_version")).scalars())
    revisions, parents = _revision_graph()
    if not stamped:
        return "empty"
    if stamped == revisions - parents and len(stamped) == 1:
        return "current"
    return "behind" if stamped <= revisions else "ahead"


def is_current(engine: Engine) -> bool:
    """Whether the database is stamped with exactly the newest revision."""
    return schema_state(engine) == "current"


def missing_sqlite_file(settings: Settings) -> Path | None:
    """The SQLite file the settings point at when it does not exist; None for an existing file or a server."""
    url = make_url(settings.resolved_database_url)
    if url.get_backend_name() != "sqlite" or not url.database or url.database == ":memory:":
        return None
    path = Path(url.database)
    return None if path.exists() else path


def database_state(settings: Settings) -> SchemaState:
    """`schema_state` of the configured database, without creating it: a SQLite file that does not exist is
    ``empty`` and stays absent (connecting would create it, and its folder)."""
    if missing_sqlite_file(settings) is not None:
        return "empty"
    engine = make_engine(settings)
    try:
        return schema_state(engine)
    finally:
        engine.dispose()


def database_name(settings: Settings) -> str:
    """The configured database for a message: a SQLite file's path, else the URL without its password."""
    return url_name(make_url(settings.resolved_database_url))


def url_name(url: URL) -> str:
    """A database URL for a message: a SQLite file's path, else the URL without its password."""
    if url.get_backend_name() == "sqlite" and url.database:
        return str(Path(url.database).resolve()) if url.database != ":memory:" else ":memory:"
    return url.render_as_string(hide_password=True)


@contextlib.contextmanager
def _migration_lock(engine: Engine) -> Iterator[None]:
    """For a SQLite file, an exclusive lock on a sibling lock file; PostgreSQL locks inside the transaction."""
    database = engine.url.database
    if engine.dialect.name != "sqlite" or not database or database == ":memory:":
        yield
        return
    with open(f"{database}.migrate.lock", "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
