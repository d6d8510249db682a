"""A remembered POST names what it created, so deleting that also forgets the request.

Revision ID: 0008_reliability
Revises: 0007
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0008_reliability"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add idempotent_requests.resource_id (null on older rows) with an index."""
    with op.batch_alter_table("idempotent_requests") as batch:
        batch.add_column(sa.Column("resource_id", sa.String(40), nullable=True))
        batch.create_index("ix_idempotent_requests_resource_id", ["resource_id"])


def downgrade() -> None:
    """Drop idempotent_requests.resource_id."""
    with op.batch_alter_table("idempotent_requests") as batch:
        batch.drop_index("ix_idempotent_requests_resource_id")
        batch.drop_column("resource_id")
