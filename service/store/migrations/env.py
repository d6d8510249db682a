"""Alembic environment: runs migrations on the connection `service.store.db.migrate` passes in, or on the URL
from the settings when Alembic is run by hand (``alembic -x`` is not needed)."""

from __future__ import annotations

from alembic import context
from sqlalchemy import Connection

import service.store.models
from service.settings import get_settings
from service.store.db import make_engine

target_metadata = service.store.models.Base.metadata


def run_on(connection: Connection) -> None:
    """Run the pending migrations on `connection` (batch mode so SQLite can alter tables)."""
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        render_as_batch=connection.dialect.name == "sqlite",
        compare_type=True,
    )
    with context.begin_transaction():
        context.run_migrations()


given = context.config.attributes.get("connection")
if given is not None:
    run_on(given)
else:
    with make_engine(get_settings()).connect() as own:
        run_on(own)
        own.commit()
