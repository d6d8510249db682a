"""Jobs, their event log and the rewards they produce.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22
"""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa
from alembic import op

from service.store.models.base import UTCDateTime

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

ID = sa.String(40)
STATUSES = "'queued', 'running', 'succeeded', 'failed', 'cancelled'"
PROGRESS = ("loss", "irl_loss", "sharing_loss", "heldout_nll", "elapsed_s")


def _progress_columns() -> list[sa.Column[Any]]:
    """Step counters and losses of a progress sample (jobs keep the latest, events each logged one)."""
    return [
        sa.Column("step", sa.Integer(), nullable=True),
        sa.Column("max_steps", sa.Integer(), nullable=True),
        *(sa.Column(name, sa.Float(), nullable=True) for name in PROGRESS),
    ]


def upgrade() -> None:
    """Create jobs, job_events and rewards."""
    op.create_table(
        "jobs",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("demonstrator_id", ID, nullable=False),
        sa.Column("task_ids", sa.JSON(), nullable=False),
        sa.Column("config", sa.JSON(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("cancel_requested", sa.Boolean(), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("max_attempts", sa.Integer(), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        *_progress_columns(),
        sa.Column("best_step", sa.Integer(), nullable=True),
        sa.Column("updated_at", UTCDateTime(), nullable=False),
        sa.Column("started_at", UTCDateTime(), nullable=True),
        sa.Column("finished_at", UTCDateTime(), nullable=True),
        sa.Column("heartbeat_at", UTCDateTime(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_jobs"),
        sa.CheckConstraint(f"status IN ({STATUSES})", name="ck_jobs_status"),
        sa.ForeignKeyConstraint(["lab_id"], ["labs.id"], name="fk_jobs_lab_id_labs", ondelete="CASCADE"),
        sa.ForeignKeyConstraint(
            ["demonstrator_id"],
            ["demonstrators.id"],
            name="fk_jobs_demonstrator_id_demonstrators",
            ondelete="CASCADE",
        ),
    )
    op.create_index("ix_jobs_demonstrator_id", "jobs", ["demonstrator_id"])
    op.create_index("ix_jobs_lab_created", "jobs", ["lab_id", "created_at", "id"])
    op.create_index("ix_jobs_status_heartbeat", "jobs", ["status", "heartbeat_at"])
    op.create_table(
        "job_events",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("job_id", ID, nullable=False),
        sa.Column("at", UTCDateTime(), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("attempt", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(16), nullable=True),
        sa.Column("message", sa.Text(), nullable=True),
        *_progress_columns(),
        sa.PrimaryKeyConstraint("id", name="pk_job_events"),
        sa.ForeignKeyConstraint(
            ["job_id"], ["jobs.id"], name="fk_job_events_job_id_jobs", ondelete="CASCADE"
        ),
    )
    op.create_index("ix_job_events_job_id", "job_events", ["job_id"])
    op.create_table(
        "rewards",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("job_id", ID, nullable=False),
        sa.Column("ordinal", sa.Integer(), nullable=False),
        sa.Column("kind", sa.String(8), nullable=False),
        sa.Column("task_id", ID, nullable=True),
        sa.Column("n_states", sa.Integer(), nullable=False),
        sa.Column("n_actions", sa.Integer(), nullable=False),
        sa.Column("reward_blob_id", ID, nullable=False),
        sa.Column("value_blob_id", ID, nullable=True),
        sa.Column("policy_blob_id", ID, nullable=True),
        sa.Column("truth_pearson", sa.Float(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_rewards"),
        sa.UniqueConstraint("job_id", "ordinal", name="uq_rewards_job_ordinal"),
        sa.ForeignKeyConstraint(["lab_id"], ["labs.id"], name="fk_rewards_lab_id_labs", ondelete="CASCADE"),
        sa.ForeignKeyConstraint(["job_id"], ["jobs.id"], name="fk_rewards_job_id_jobs", ondelete="CASCADE"),
        sa.ForeignKeyConstraint(
            ["task_id"], ["tasks.id"], name="fk_rewards_task_id_tasks", ondelete="CASCADE"
        ),
        *(
            sa.ForeignKeyConstraint(
                [f"{name}_blob_id"], ["blobs.id"], name=f"fk_rewards_{name}_blob_id_blobs"
            )
            for name in ("reward", "value", "policy")
        ),
    )
    op.create_index("ix_rewards_lab_id", "rewards", ["lab_id"])
    op.create_index("ix_rewards_task_id", "rewards", ["task_id"])


def downgrade() -> None:
    """Drop the job tables (children first)."""
    for table in ("rewards", "job_events", "jobs"):
        op.drop_table(table)
