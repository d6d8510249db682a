"""Each reward row keeps its spread across the ensemble's members and the demonstrations' evidence per state.

Revision ID: 0010_uncertainty
Revises: 0007
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0010_uncertainty"
down_revision = "0009_standing"
branch_labels = None
depends_on = None


QUANTITIES = ("uncertainty", "evidence")
"""The new per-state arrays of a reward row, each a blob."""


def upgrade() -> None:
    """Add rewards.uncertainty_blob_id and .evidence_blob_id (null on older rows: not computed then)."""
    with op.batch_alter_table("rewards") as batch:
        for name in QUANTITIES:
            batch.add_column(sa.Column(f"{name}_blob_id", sa.String(40), nullable=True))
            batch.create_foreign_key(f"fk_rewards_{name}_blob_id_blobs", "blobs", [f"{name}_blob_id"], ["id"])


def downgrade() -> None:
    """Drop rewards.uncertainty_blob_id and .evidence_blob_id."""
    with op.batch_alter_table("rewards") as batch:
        for name in reversed(QUANTITIES):
            batch.drop_constraint(f"fk_rewards_{name}_blob_id_blobs", type_="foreignkey")
            batch.drop_column(f"{name}_blob_id")
