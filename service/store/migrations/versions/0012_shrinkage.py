"""A succeeded job keeps the λ its task rewards were shrunk toward the baseline by.

Revision ID: 0012_shrinkage
Revises: 0011_step_history
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0012_shrinkage"
down_revision = "0011_step_history"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add jobs.shrinkage (null on jobs that succeeded before: not kept then)."""
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("shrinkage", sa.Float(), nullable=True))


def downgrade() -> None:
    """Drop jobs.shrinkage in place (SQLite 3.35+ can): a batch copy would drop the old jobs table, and on
    SQLite with foreign keys on that deletes every job's events, rewards and steps with it."""
    op.drop_column("jobs", "shrinkage")
