"""Remembered POST responses by `Idempotency-Key`, per lab, so a retried request creates nothing new."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import JSON, ForeignKey, Integer, LargeBinary, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin, UTCDateTime


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
    claim: Mapped[str | None] = mapped_column(String(32))
    """Random id of the request holding a running claim: only that request renews, records or releases it."""
    resource_id: Mapped[str | None] = mapped_column(String(ID_LENGTH), index=True)
    """The ``id`` of what a successful request created: deleting that forgets the request (no replay of it)."""
    leased_until: Mapped[datetime | None] = mapped_column(UTCDateTime())
    """While running, when the claim lapses unless its request renews it (null: lapsed); a retry with the
    same key and body then takes the claim over."""
