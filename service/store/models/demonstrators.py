"""Demonstrators, their tasks, uploaded demonstrations and optional true rewards."""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, ForeignKey, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin, UTCDateTime, utcnow


class Demonstrator(CreatedAtMixin, Base):
    """A person, robot or session whose shared (baseline) reward is learned across its tasks."""

    __tablename__ = "demonstrators"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    meta: Mapped[dict[str, Any] | None] = mapped_column("metadata", JSON)


class Task(CreatedAtMixin, Base):
    """One task of a demonstrator, played in one MDP."""

    __tablename__ = "tasks"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    demonstrator_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("demonstrators.id", ondelete="CASCADE"), index=True
    )
    mdp_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("mdps.id"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    meta: Mapped[dict[str, Any] | None] = mapped_column("metadata", JSON)


class Demonstration(CreatedAtMixin, Base):
    """One upload batch of trajectories for a task (uploads append; a batch is all-or-nothing).

    Blobs: ``states`` and ``actions`` concatenated over trajectories (int32), ``lengths`` (n, 2) int32
    holding each trajectory's number of states and of actions.
    """

    __tablename__ = "demonstrations"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    task_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("tasks.id", ondelete="CASCADE"), index=True
    )
    format: Mapped[str] = mapped_column(String(8))
    """``json`` or ``csv``: how the batch was uploaded."""
    n_trajectories: Mapped[int] = mapped_column(Integer)
    n_steps: Mapped[int] = mapped_column(Integer)
    """Number of demonstrated (state, action) pairs in the batch."""
    states_blob_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    actions_blob_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    lengths_blob_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))


class TrueReward(Base):
    """The known reward of a simulated task (one per task, replaced by PUT), for scoring learned rewards."""

    __tablename__ = "true_rewards"

    task_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("tasks.id", ondelete="CASCADE"), primary_key=True
    )
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    blob_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    n_states: Mapped[int] = mapped_column(Integer)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime(), default=utcnow, onupdate=utcnow)
