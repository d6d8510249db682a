"""The async database path of the hot read routes (`GET /v1/jobs/{id}`, stored reward downloads).

Those routes run on the event loop and read with SQLAlchemy's asyncio extension (asyncpg on PostgreSQL,
aiosqlite on SQLite) instead of holding a thread of FastAPI's pool around sync statements: the key check and
the read are one statement (`service.api.auth.authorised_row`), on an autocommit connection.

The engine is made by the app's lifespan, once per API process, and handed to requests as lifespan state
(`ENGINE`); it is disposed at shutdown. Its pooled connections belong to the lifespan's event loop, so a
request served without the lifespan (a test client not entered with ``with``, which runs each request on a
loop of its own) gets an unpooled engine for that request instead.

A database that cannot be reached, or a connection that dropped, is the same 503 problem as on the sync routes
(`service.problems.database_unavailable`): asyncpg reports these as ``OSError`` or as DBAPI errors of a lost
connection, which the app's `OperationalError` handler does not see.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import Request
from sqlalchemy.exc import DBAPIError, InterfaceError
from sqlalchemy.ext.asyncio import AsyncConnection, AsyncEngine

from service.problems import database_unavailable
from service.settings import Settings
from service.store.db import make_async_engine

ENGINE = "async_engine"
"""The lifespan state's name for the process's async engine."""

log = logging.getLogger(__name__)


@asynccontextmanager
async def async_engine(settings: Settings) -> AsyncIterator[dict[str, AsyncEngine]]:
    """The lifespan's part: the pooled async engine as lifespan state, disposed when the app shuts down."""
    engine = make_async_engine(settings)
    try:
        yield {ENGINE: engine}
    finally:
        await engine.dispose()


@asynccontextmanager
async def connection(request: Request) -> AsyncIterator[AsyncConnection]:
    """An autocommit connection for this request, from the lifespan's engine (or a one-off engine without a
    lifespan); a lost or unreachable database raises the 503 problem."""
    engine: AsyncEngine | None = getattr(request.state, ENGINE, None)
    own = None
    if engine is None:
        engine = own = make_async_engine(request.app.state.settings, pooled=False)
    try:
        try:
            db = await engine.connect()
        except (OSError, DBAPIError) as exc:  # refused, timed out, or turned away (starting up, no database)
            raise _unavailable(request, exc) from exc
        try:
            yield db
        except (OSError, InterfaceError) as exc:  # the connection dropped during a statement
            raise _unavailable(request, exc) from exc
        except DBAPIError as exc:
            if exc.connection_invalidated:
                raise _unavailable(request, exc) from exc
            raise
        finally:
            await db.close()
    finally:
        if own is not None:
            await own.dispose()


def _unavailable(request: Request, exc: Exception) -> Exception:
    """The 503 problem for a database failure on `request`, logged like the sync routes' (`service.problems`)."""
    log.warning("database unavailable on %s %s: %s", request.method, request.url.path, exc)
    return database_unavailable()
