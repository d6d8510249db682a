"""Remembered POST responses by `Idempotency-Key`, per lab, so a retried request creates nothing new."""

from __future__ import annotations

from sqlalchemy import JSON, ForeignKey, Integer, LargeBinary, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin


class IdempotentRequest(CreatedAtMixin, Base):
    """A claimed key: the request's fingerprint and, once finished, its response (`status` None = running)."""

    __tablename__ = "idempotent_requests"

    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), primary_key=True
    )
    key: Mapped[str] = mapped_column(String(255), primary_key=True)
    fingerprint: Mapped[str] = mapped_column(String(64))
    status: Mapped[int | None] = mapped_column(Integer)
    headers: Mapped[list[list[str]] | None] = mapped_column(JSON)
    body: Mapped[bytes | None] = mapped_column(LargeBinary)
