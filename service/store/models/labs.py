"""Tenants and their API keys: every resource row has a `lab_id`, every request is made by one lab."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import ForeignKey, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin, UTCDateTime


class Lab(CreatedAtMixin, Base):
    """A lab (tenant): owns MDPs, demonstrators, tasks, jobs and rewards."""

    __tablename__ = "labs"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)


class ApiKey(CreatedAtMixin, Base):
    """One API key of a lab, stored as the SHA-256 of its secret part; `id` is the key's public part."""

    __tablename__ = "api_keys"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    secret_sha256: Mapped[str] = mapped_column(String(64))
    revoked_at: Mapped[datetime | None] = mapped_column(UTCDateTime(), default=None)
    last_used_at: Mapped[datetime | None] = mapped_column(UTCDateTime(), default=None)
    """When a request last authenticated with it (written at most every `LAST_USED_RESOLUTION_S`)."""
