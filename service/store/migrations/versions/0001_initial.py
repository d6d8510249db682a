"""Initial schema: labs and keys, blobs, MDPs, demonstrators, tasks, demonstrations, true rewards, idempotency.

Revision ID: 0001
Revises:
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from service.store.models.base import UTCDateTime

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

ID = sa.String(40)


def _lab_fk(table: str) -> sa.ForeignKeyConstraint:
    """The `lab_id` → labs.id foreign key every tenant-owned table has."""
    return sa.ForeignKeyConstraint(
        ["lab_id"], ["labs.id"], name=f"fk_{table}_lab_id_labs", ondelete="CASCADE"
    )


def upgrade() -> None:
    """Create every table of the first release."""
    op.create_table(
        "labs",
        sa.Column("id", ID, nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_labs"),
        sa.UniqueConstraint("name", name="uq_labs_name"),
    )
    op.create_table(
        "api_keys",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("secret_sha256", sa.String(64), nullable=False),
        sa.Column("revoked_at", UTCDateTime(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_api_keys"),
        _lab_fk("api_keys"),
    )
    op.create_index("ix_api_keys_lab_id", "api_keys", ["lab_id"])
    op.create_table(
        "blobs",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("dtype", sa.String(8), nullable=False),
        sa.Column("shape", sa.JSON(), nullable=False),
        sa.Column("nbytes", sa.BigInteger(), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_blobs"),
        _lab_fk("blobs"),
    )
    op.create_index("ix_blobs_lab_id", "blobs", ["lab_id"])
    op.create_table(
        "mdps",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("source", sa.String(16), nullable=False),
        sa.Column("n_states", sa.Integer(), nullable=False),
        sa.Column("n_actions", sa.Integer(), nullable=False),
        sa.Column("n_features", sa.Integer(), nullable=True),
        sa.Column("gamma", sa.Float(), nullable=False),
        sa.Column("transitions", sa.String(16), nullable=False),
        sa.Column("layout", sa.JSON(), nullable=True),
        sa.Column("grid", sa.JSON(), nullable=True),
        sa.Column("summary", sa.JSON(), nullable=False),
        sa.Column("array_blobs", sa.JSON(), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_mdps"),
        _lab_fk("mdps"),
    )
    op.create_index("ix_mdps_lab_id", "mdps", ["lab_id"])
    op.create_table(
        "demonstrators",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("metadata", sa.JSON(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_demonstrators"),
        _lab_fk("demonstrators"),
    )
    op.create_index("ix_demonstrators_lab_id", "demonstrators", ["lab_id"])
    op.create_table(
        "tasks",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("demonstrator_id", ID, nullable=False),
        sa.Column("mdp_id", ID, nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("metadata", sa.JSON(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_tasks"),
        _lab_fk("tasks"),
        sa.ForeignKeyConstraint(
            ["demonstrator_id"],
            ["demonstrators.id"],
            name="fk_tasks_demonstrator_id_demonstrators",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(["mdp_id"], ["mdps.id"], name="fk_tasks_mdp_id_mdps"),
    )
    op.create_index("ix_tasks_lab_id", "tasks", ["lab_id"])
    op.create_index("ix_tasks_demonstrator_id", "tasks", ["demonstrator_id"])
    op.create_index("ix_tasks_mdp_id", "tasks", ["mdp_id"])
    op.create_table(
        "demonstrations",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("task_id", ID, nullable=False),
        sa.Column("format", sa.String(8), nullable=False),
        sa.Column("n_trajectories", sa.Integer(), nullable=False),
        sa.Column("n_steps", sa.Integer(), nullable=False),
        sa.Column("states_blob_id", ID, nullable=False),
        sa.Column("actions_blob_id", ID, nullable=False),
        sa.Column("lengths_blob_id", ID, nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_demonstrations"),
        _lab_fk("demonstrations"),
        sa.ForeignKeyConstraint(
            ["task_id"], ["tasks.id"], name="fk_demonstrations_task_id_tasks", ondelete="CASCADE"
        ),
        *(
            sa.ForeignKeyConstraint(
                [f"{name}_blob_id"], ["blobs.id"], name=f"fk_demonstrations_{name}_blob_id_blobs"
            )
            for name in ("states", "actions", "lengths")
        ),
    )
    op.create_index("ix_demonstrations_lab_id", "demonstrations", ["lab_id"])
    op.create_index("ix_demonstrations_task_id", "demonstrations", ["task_id"])
    op.create_table(
        "true_rewards",
        sa.Column("task_id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("blob_id", ID, nullable=False),
        sa.Column("n_states", sa.Integer(), nullable=False),
        sa.Column("updated_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("task_id", name="pk_true_rewards"),
        _lab_fk("true_rewards"),
        sa.ForeignKeyConstraint(
            ["task_id"], ["tasks.id"], name="fk_true_rewards_task_id_tasks", ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(["blob_id"], ["blobs.id"], name="fk_true_rewards_blob_id_blobs"),
    )
    op.create_index("ix_true_rewards_lab_id", "true_rewards", ["lab_id"])
    op.create_table(
        "idempotent_requests",
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("key", sa.String(255), nullable=False),
        sa.Column("fingerprint", sa.String(64), nullable=False),
        sa.Column("status", sa.Integer(), nullable=True),
        sa.Column("headers", sa.JSON(), nullable=True),
        sa.Column("body", sa.LargeBinary(), nullable=True),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("lab_id", "key", name="pk_idempotent_requests"),
        _lab_fk("idempotent_requests"),
    )


def downgrade() -> None:
    """Drop every table of the first release (children first)."""
    for table in (
        "idempotent_requests",
        "true_rewards",
        "demonstrations",
        "tasks",
        "demonstrators",
        "mdps",
        "blobs",
        "api_keys",
        "labs",
    ):
        op.drop_table(table)
