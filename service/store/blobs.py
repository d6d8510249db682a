"""Arrays in the database: little-endian float32/int32 bytes plus shape, dtype and SHA-256 (never pickle)."""

from __future__ import annotations

import hashlib

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session, undefer

from service.store.ids import new_id
from service.store.models.blobs import Blob

STORED_DTYPES = {"f": np.dtype("<f4"), "i": np.dtype("<i4"), "u": np.dtype("<i4"), "b": np.dtype("<i4")}
"""numpy dtype kind → the stored dtype: floats as float32, integers and booleans as int32."""


def put_array(session: Session, array: np.ndarray, *, lab_id: str) -> str:
    """Add `array` (converted to float32 or int32) as a new blob of `lab_id`; returns the blob id."""
    arr = np.asarray(array)
    dtype = STORED_DTYPES.get(arr.dtype.kind)
    if dtype is None:
        raise TypeError(f"cannot store arrays of dtype {arr.dtype}")
    data = np.ascontiguousarray(arr, dtype=dtype).tobytes()
    blob = Blob(
        id=new_id("blob"),
        lab_id=lab_id,
        dtype=dtype.str,
        shape=[int(n) for n in arr.shape],
        nbytes=len(data),
        sha256=hashlib.sha256(data).hexdigest(),
        data=data,
    )
    session.add(blob)
    return blob.id


def get_array(session: Session, blob_id: str) -> np.ndarray:
    """The stored array (a writable copy) of blob `blob_id`."""
    blob = session.execute(select(Blob).options(undefer(Blob.data)).where(Blob.id == blob_id)).scalar_one()
    return np.frombuffer(blob.data, dtype=np.dtype(blob.dtype)).reshape(blob.shape).copy()


def blob_sha256(session: Session, blob_id: str) -> str:
    """The SHA-256 (hex) of a blob's bytes, without loading them."""
    return session.execute(select(Blob.sha256).where(Blob.id == blob_id)).scalar_one()
