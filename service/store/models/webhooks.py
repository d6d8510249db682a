"""Webhooks of a lab (a URL called when its jobs end) and their deliveries, one row per event and webhook.

A delivery row is written in the same transaction as the job's final status (`service.jobs.transitions`),
so no ending is ever missed; the workers send it, retried with exponential backoff until it is
``delivered`` or, after ``webhook_max_attempts``, ``failed``.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, ForeignKey, Index, Integer, String, Text
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin, UTCDateTime, utcnow


class Webhook(CreatedAtMixin, Base):
    """A URL of a lab and the job events it wants; ``secret`` signs every delivery (Standard Webhooks)."""

    __tablename__ = "webhooks"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    url: Mapped[str] = mapped_column(Text)
    events: Mapped[list[str]] = mapped_column(JSON)
    secret: Mapped[str] = mapped_column(String(100))
    """``whsec_`` + base64 of the signing key (kept to sign; shown to the lab once)."""


class WebhookDelivery(CreatedAtMixin, Base):
    """One event to send to one webhook: its body, and how sending it went so far."""

    __tablename__ = "webhook_deliveries"
    __table_args__ = (Index("ix_webhook_deliveries_status_next", "status", "next_attempt_at"),)

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    """Also the ``webhook-id`` header: the same for every attempt, so receivers can drop duplicates."""
    webhook_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("webhooks.id", ondelete="CASCADE"), index=True
    )
    job_id: Mapped[str] = mapped_column(String(ID_LENGTH))
    type: Mapped[str] = mapped_column(String(32))
    payload: Mapped[dict[str, Any]] = mapped_column(JSON)
    status: Mapped[str] = mapped_column(String(16), default="pending")
    """``pending`` (to send, at ``next_attempt_at``), ``delivered`` or ``failed`` (attempts used up)."""
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    next_attempt_at: Mapped[datetime | None] = mapped_column(UTCDateTime(), default=utcnow)
    last_attempt_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
    last_status_code: Mapped[int | None] = mapped_column(Integer)
    last_error: Mapped[str | None] = mapped_column(Text)
    delivered_at: Mapped[datetime | None] = mapped_column(UTCDateTime())
