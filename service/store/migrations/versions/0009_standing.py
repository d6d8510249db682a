"""Quiet-standing recordings: a recording's protocol and lab metadata; a standing one maps onto no MDP.

Revision ID: 0009_standing
Revises: 0007
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0009_standing"
down_revision = "0008_reliability"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Add recordings.protocol (``movements`` for existing rows) and .metadata; let mdp_id be null."""
    with op.batch_alter_table("recordings") as batch:
        batch.add_column(sa.Column("protocol", sa.String(16), nullable=False, server_default="movements"))
        batch.add_column(sa.Column("metadata", sa.JSON(), nullable=True))
        batch.alter_column("mdp_id", existing_type=sa.String(40), nullable=True)


def downgrade() -> None:
    """Drop standing recordings (they have no MDP), then the two columns, and make mdp_id required again."""
    op.execute("DELETE FROM recordings WHERE mdp_id IS NULL")
    with op.batch_alter_table("recordings") as batch:
        batch.alter_column("mdp_id", existing_type=sa.String(40), nullable=False)
        batch.drop_column("metadata")
        batch.drop_column("protocol")
