"""Rewards keep their summary statistics; the stored truth_pearson goes (it is computed on request).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-22
"""

from __future__ import annotations

import numpy as np
import sqlalchemy as sa
from alembic import op

from service.files import exports

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add rewards.summary, computed from each existing reward's stored array, and drop truth_pearson."""
    with op.batch_alter_table("rewards") as batch:
        batch.add_column(sa.Column("summary", sa.JSON(), nullable=True))
        batch.drop_column("truth_pearson")
    rewards = sa.table("rewards", sa.column("id", sa.String), sa.column("summary", sa.JSON))
    connection = op.get_bind()
    rows = connection.execute(
        sa.text("SELECT r.id, b.dtype, b.data FROM rewards r JOIN blobs b ON b.id = r.reward_blob_id")
    )
    for reward_id, dtype, data in rows.fetchall():
        values = np.frombuffer(bytes(data), dtype=np.dtype(dtype))
        connection.execute(
            rewards.update().where(rewards.c.id == reward_id).values(summary=exports.summary(values))
        )
    with op.batch_alter_table("rewards") as batch:
        batch.alter_column("summary", existing_type=sa.JSON(), nullable=False)


def downgrade() -> None:
    """Restore truth_pearson (empty) and drop summary."""
    with op.batch_alter_table("rewards") as batch:
        batch.add_column(sa.Column("truth_pearson", sa.Float(), nullable=True))
        batch.drop_column("summary")
