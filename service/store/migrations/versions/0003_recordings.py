"""Centre-of-pressure recordings of demonstrators (motion analysis uploads).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-22
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from service.store.models.base import UTCDateTime

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

ID = sa.String(40)


def upgrade() -> None:
    """Create the recordings table."""
    op.create_table(
        "recordings",
        sa.Column("id", ID, nullable=False),
        sa.Column("lab_id", ID, nullable=False),
        sa.Column("demonstrator_id", ID, nullable=False),
        sa.Column("mdp_id", ID, nullable=False),
        sa.Column("name", sa.String(200), nullable=True),
        sa.Column("format", sa.String(8), nullable=False),
        sa.Column("n_samples", sa.Integer(), nullable=False),
        sa.Column("duration", sa.Float(), nullable=False),
        sa.Column("samples_blob_id", ID, nullable=False),
        sa.Column("instructions_blob_id", ID, nullable=True),
        sa.Column("settings", sa.JSON(), nullable=False),
        sa.Column("summary", sa.JSON(), nullable=False),
        sa.Column("created_at", UTCDateTime(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_recordings"),
        sa.ForeignKeyConstraint(
            ["lab_id"], ["labs.id"], name="fk_recordings_lab_id_labs", ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["demonstrator_id"],
            ["demonstrators.id"],
            name="fk_recordings_demonstrator_id_demonstrators",
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(["mdp_id"], ["mdps.id"], name="fk_recordings_mdp_id_mdps"),
        *(
            sa.ForeignKeyConstraint(
                [f"{name}_blob_id"], ["blobs.id"], name=f"fk_recordings_{name}_blob_id_blobs"
            )
            for name in ("samples", "instructions")
        ),
    )
    op.create_index("ix_recordings_lab_id", "recordings", ["lab_id"])
    op.create_index("ix_recordings_demonstrator_id", "recordings", ["demonstrator_id"])


def downgrade() -> None:
    """Drop the recordings table."""
    op.drop_table("recordings")
