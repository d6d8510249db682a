"""Centre-of-pressure recordings uploaded through `/v1/demonstrators/{id}/recordings` (docs/motion.md).

A row keeps the raw samples (so a recording can be re-processed), the settings it was cut with and the
summary returned on upload; the demonstrations it produced are ordinary `Demonstration` batches of tasks.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import JSON, Float, ForeignKey, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin


class Recording(CreatedAtMixin, Base):
    """One COP recording of a demonstrator: cut into movements on a velocity-grid MDP, or (``standing``) kept
    whole for its sway measures, with no MDP.

    Blobs: ``samples`` (N, 3) float32 columns t, x, y; ``instructions`` (N,) int32 index into
    `metairl_engine.grids.DIRECTION_NAMES` (-1: no instruction), absent when the upload had no instructions.
    """

    __tablename__ = "recordings"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    demonstrator_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("demonstrators.id", ondelete="CASCADE"), index=True
    )
    mdp_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), ForeignKey("mdps.id"))
    protocol: Mapped[str] = mapped_column(String(16), server_default="movements")
    """``movements`` (out-and-back movements cut into demonstrations) or ``standing`` (stored whole)."""
    meta: Mapped[dict[str, Any] | None] = mapped_column("metadata", JSON)
    """The lab's labels of the trial, e.g. ``{"vision": "closed", "surface": "foam"}``."""
    name: Mapped[str | None] = mapped_column(String(200))
    format: Mapped[str] = mapped_column(String(8))
    """``json``, ``csv``, ``c3d`` or ``forces`` (a CSV of plate forces and moments): how the samples came."""
    n_samples: Mapped[int] = mapped_column(Integer)
    duration: Mapped[float] = mapped_column(Float)
    """Last minus first sample time, in the recording's time unit."""
    samples_blob_id: Mapped[str] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    instructions_blob_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), ForeignKey("blobs.id"))
    settings: Mapped[dict[str, Any]] = mapped_column(JSON)
    """Plate bounds and the discretise/segment settings used (every default filled in); ``plate`` for a
    force-plate file: how it was read."""
    summary: Mapped[dict[str, Any]] = mapped_column(JSON)
    """Segments per label, tasks created or joined, dropped samples and segments."""
