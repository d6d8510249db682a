"""A succeeded job keeps the share of each task's deviation from the baseline that was set to zero.

Revision ID: 0013_sparsity
Revises: 0012_shrinkage
Create Date: 2026-11-26
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0013_sparsity"
down_revision = "0012_shrinkage"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add jobs.sparsity (null on jobs that succeeded before: not kept then)."""
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("sparsity", sa.Float(), nullable=True))


def downgrade() -> None:
    """Drop jobs.sparsity in place, as 0012 drops jobs.shrinkage (a batch copy would cascade deletes)."""
    op.drop_column("jobs", "sparsity")
