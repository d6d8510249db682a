"""API keys remember when they were last used (shown by `metairl keys list`).

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from service.store.models.base import UTCDateTime

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add api_keys.last_used_at (null: never used)."""
    with op.batch_alter_table("api_keys") as batch:
        batch.add_column(sa.Column("last_used_at", UTCDateTime(), nullable=True))


def downgrade() -> None:
    """Drop api_keys.last_used_at."""
    with op.batch_alter_table("api_keys") as batch:
        batch.drop_column("last_used_at")
