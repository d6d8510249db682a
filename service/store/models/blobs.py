"""Stored arrays: little-endian float32/int32 bytes with shape, dtype and SHA-256 (never pickle)."""

from __future__ import annotations

from sqlalchemy import JSON, BigInteger, ForeignKey, LargeBinary, String
from sqlalchemy.orm import Mapped, mapped_column

from service.store.models.base import ID_LENGTH, Base, CreatedAtMixin


class Blob(CreatedAtMixin, Base):
    """One array; `data` is deferred so metadata queries never load payloads."""

    __tablename__ = "blobs"

    id: Mapped[str] = mapped_column(String(ID_LENGTH), primary_key=True)
    lab_id: Mapped[str] = mapped_column(
        String(ID_LENGTH), ForeignKey("labs.id", ondelete="CASCADE"), index=True
    )
    dtype: Mapped[str] = mapped_column(String(8))
    shape: Mapped[list[int]] = mapped_column(JSON)
    nbytes: Mapped[int] = mapped_column(BigInteger)
    sha256: Mapped[str] = mapped_column(String(64))
    data: Mapped[bytes] = mapped_column(LargeBinary, deferred=True)
