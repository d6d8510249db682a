"""An in-progress Idempotency-Key claim holds a lease, so a claim whose request died is taken over.

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from service.store.models.base import UTCDateTime

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add idempotent_requests.claim and .leased_until (null on older rows: a running one has lapsed)."""
    with op.batch_alter_table("idempotent_requests") as batch:
        batch.add_column(sa.Column("claim", sa.String(32), nullable=True))
        batch.add_column(sa.Column("leased_until", UTCDateTime(), nullable=True))


def downgrade() -> None:
    """Drop idempotent_requests.claim and .leased_until."""
    with op.batch_alter_table("idempotent_requests") as batch:
        batch.drop_column("leased_until")
        batch.drop_column("claim")
