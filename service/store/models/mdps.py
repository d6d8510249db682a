"""MDP rows: metadata and summary in columns, arrays in blobs (so listing MDPs loads no arrays)."""

from __future__ import annotations

from typing import Any

from sqlalchemy import JSON, Float, ForeignKey, Integer, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin


class Mdp(CreatedAtMixin, Base):
    """A validated MDP of one lab; `array_blobs` maps the `.npz` array names of docs/api.md to blob ids."""

    __tablename__ = "mdps"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    name: Mapped[str] = mapped_column(String(200))
    source: Mapped[str] = mapped_column(String(16))
    """How it was created: ``explicit`` (JSON arrays), ``grid`` (built server side) or ``npz`` (upload)."""
    n_states: Mapped[int] = mapped_column(Integer)
    n_actions: Mapped[int] = mapped_column(Integer)
    n_features: Mapped[int | None] = mapped_column(Integer)
    """Feature width, or None for tabular (one-hot) features."""
    gamma: Mapped[float] = mapped_column(Float)
    transitions: Mapped[str] = mapped_column(String(16))
    """``deterministic`` or ``sparse``."""
    layout: Mapped[dict[str, int] | None] = mapped_column(JSON)
    grid: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    """The grid parameters for ``source == "grid"``."""
    summary: Mapped[dict[str, Any]] = mapped_column(JSON)
    array_blobs: Mapped[dict[str, str]] = mapped_column(JSON)
