"""A succeeded job keeps every step's losses of its fit, columnar, beside its rewards.

Revision ID: 0011_step_history
Revises: 0010_uncertainty
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0011_step_history"
down_revision = "0010_uncertainty"
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Create job_step_histories, one row per succeeded job (jobs finished before have none)."""
    op.create_table(
        "job_step_histories",
        sa.Column("job_id", sa.String(40), nullable=False),
        sa.Column("attempt", sa.Integer(), nullable=False),
        sa.Column("max_steps", sa.Integer(), nullable=False),
        sa.Column("n_steps", sa.Integer(), nullable=False),
        sa.Column("fields", sa.JSON(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.PrimaryKeyConstraint("job_id", name="pk_job_step_histories"),
        sa.ForeignKeyConstraint(
            ["job_id"], ["jobs.id"], name="fk_job_step_histories_job_id_jobs", ondelete="CASCADE"
        ),
    )


def downgrade() -> None:
    """Drop job_step_histories (the curves fall back to the progress samples)."""
    op.drop_table("job_step_histories")
