"""Reward, value and policy arrays as downloads (npy, csv, json), their file names, ETags and summaries.

numpy only and pure (no routes, no database) so the API process can serve results without torch and the
functions can be tested on plain arrays. A reward or value is a vector of shape (S,); a policy is (S, A).
States of a `Layout` are numbered ``state = (channel * height + y) * width + x`` (metairl_engine.mdp).
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import unicodedata

import numpy as np

from metairl_engine.mdp import Layout

EXPORT_VERSION = "1"
"""Part of every ETag: bump it whenever the bytes produced here or in service.files.images change for the same data."""

_QUANTITY = re.compile(r"[a-z][a-z0-9_]{0,31}")
_EXT = re.compile(r"[a-z0-9]{1,8}")
_MAX_PART = 40


def as_values(values: object) -> np.ndarray:
    """Coerce to a finite float32 array of shape (S,) or (S, A); raise ValueError saying why not."""
    arr = np.asarray(values, dtype=np.float32)
    if arr.ndim not in (1, 2) or arr.shape[0] == 0:
        raise ValueError(f"values must have shape (n_states,) or (n_states, n_actions), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("values must be finite (no NaN or infinity)")
    return arr


def grid_coordinates(states: object, layout: Layout) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised inverse of ``state = (channel * height + y) * width + x``: int64 (x, y, channel) arrays."""
    arr = np.asarray(states)
    if arr.dtype.kind not in "iu":
        raise ValueError(f"states must be integers, got {arr.dtype}")
    arr = arr.astype(np.int64)
    n_states = layout.width * layout.height * layout.channels
    if arr.size and (arr.min() < 0 or arr.max() >= n_states):
        raise ValueError(f"states must lie in 0..{n_states - 1} for layout {layout}")
    rest, x = np.divmod(arr, layout.width)
    channel, y = np.divmod(rest, layout.height)
    return x, y, channel


def to_npy(values: object) -> bytes:
    """The values as a float32 ``.npy`` file (no pickle): `np.load` gives back exactly the same array."""
    buf = io.BytesIO()
    np.save(buf, as_values(values), allow_pickle=False)
    return buf.getvalue()


def npy_from_stored(data: bytes, *, dtype: str, shape: list[int] | tuple[int, ...]) -> bytes:
    """The ``.npy`` file of stored little-endian bytes as they are (no copy through numpy, no re-check):
    the same bytes `to_npy` makes of a float32 array. Other stored dtypes go through `to_npy`."""
    if np.dtype(dtype) != np.dtype("<f4"):
        return to_npy(np.frombuffer(data, dtype=np.dtype(dtype)).reshape(shape))
    header = io.BytesIO()
    meta = {"descr": "<f4", "fortran_order": False, "shape": tuple(int(n) for n in shape)}
    np.lib.format.write_array_header_1_0(header, meta)
    return header.getvalue() + data


def to_csv(values: object, *, layout: Layout | None, quantity: str) -> str:
    """CSV text: header, then one row per state with ``state[,x,y,channel]`` and the value(s).

    A vector gets one column named `quantity`; a policy (S, A) gets one column per action ``a0..a{A-1}``.
    Floats are printed with ``%.9g``, enough to read every float32 back exactly.
    """
    arr = as_values(values)
    _check_quantity(quantity)
    n_states = arr.shape[0]
    index = np.arange(n_states, dtype=np.int64)
    columns: list[np.ndarray] = [index]
    header = ["state"]
    if layout is not None:
        check_layout(layout, n_states)
        columns += grid_coordinates(index, layout)
        header += ["x", "y", "channel"]
    value_columns = arr.reshape(n_states, -1).astype(np.float64)
    header += [f"a{k}" for k in range(arr.shape[1])] if arr.ndim == 2 else [quantity]
    table = np.column_stack([*(c.astype(np.float64) for c in columns), value_columns])
    fmt = ["%d"] * len(columns) + ["%.9g"] * value_columns.shape[1]
    buf = io.StringIO()
    np.savetxt(buf, table, fmt=fmt, delimiter=",", header=",".join(header), comments="")
    return buf.getvalue()


def to_json(values: object, *, reward_id: str, quantity: str) -> str:
    """JSON text ``{"reward_id", "quantity", "n_states", "values"}`` (docs/api.md, "Rewards"); a policy adds ``n_actions``.

    ``values`` is a list of numbers, or for a policy a list of rows; each number is printed in the shortest
    form that reads back as the same float32. Returned as text so the route sends it without re-encoding.
    """
    arr = as_values(values)
    _check_quantity(quantity)
    head = {"reward_id": reward_id, "quantity": quantity, "n_states": int(arr.shape[0])}
    if arr.ndim == 2:
        head["n_actions"] = int(arr.shape[1])
        body = ",".join("[" + ",".join(row) + "]" for row in arr.astype(str).tolist())
    else:
        body = ",".join(arr.astype(str).tolist())
    return json.dumps(head)[:-1] + ', "values": [' + body + "]}"


def download_filename(*, demonstrator: str, task: str | None, quantity: str, ext: str) -> str:
    """A safe ASCII file name such as ``patient-3_forward_reward.csv`` (``baseline`` when task is None)."""
    _check_quantity(quantity)
    ext = ext.lstrip(".").lower()
    if not _EXT.fullmatch(ext):
        raise ValueError(f"file extension must be 1-8 letters or digits, got {ext!r}")
    parts = [
        _slug(demonstrator, fallback="demonstrator"),
        "baseline" if task is None else _slug(task, fallback="task"),
        quantity.replace("_", "-"),
    ]
    return "_".join(parts) + "." + ext


def etag_for(sha256: str, *variant: str | int | float | bool | None) -> str:
    """A strong HTTP ETag (quoted) for the stored array with digest `sha256` rendered as `variant`.

    The variant (format, quantity, dpi, ...) and `EXPORT_VERSION` are hashed in, so each download of the
    same array gets its own tag and a change of output format invalidates cached copies.
    """
    if not re.fullmatch(r"[0-9a-fA-F]{64}", sha256):
        raise ValueError("sha256 must be 64 hexadecimal digits")
    key = json.dumps([EXPORT_VERSION, sha256.lower(), *variant], separators=(",", ":"))
    return '"' + hashlib.sha256(key.encode()).hexdigest()[:32] + '"'


def summary(values: object) -> dict[str, float | int]:
    """Min, max, mean, std (population) and the states of the max and min of a reward vector."""
    arr = as_values(values)
    if arr.ndim != 1:
        raise ValueError(f"summary needs a vector of shape (n_states,), got {arr.shape}")
    wide = arr.astype(np.float64)
    return {
        "min": float(wide.min()),
        "max": float(wide.max()),
        "mean": float(wide.mean()),
        "std": float(wide.std()),
        "argmax_state": int(wide.argmax()),
        "argmin_state": int(wide.argmin()),
    }


def _check_quantity(quantity: str) -> None:
    """Quantities become CSV headers and file-name parts, so they must be short lowercase identifiers."""
    if not _QUANTITY.fullmatch(quantity):
        raise ValueError(f"quantity must be a lowercase identifier such as 'reward', got {quantity!r}")


def check_layout(layout: Layout, n_states: int) -> None:
    """Raise ValueError when `layout` does not tile exactly `n_states` states."""
    if layout.width < 1 or layout.height < 1 or layout.channels < 1:
        raise ValueError(f"layout sizes must be positive, got {layout}")
    if layout.width * layout.height * layout.channels != n_states:
        raise ValueError(
            f"layout {layout.width}×{layout.height}×{layout.channels} does not match {n_states} states"
        )


def _slug(text: str, *, fallback: str) -> str:
    """Lowercase ASCII letters, digits and single hyphens, at most 40 characters ('Pátient 3' → 'patient-3')."""
    ascii_text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode()
    slug = re.sub(r"[^a-z0-9]+", "-", ascii_text.lower()).strip("-")[:_MAX_PART].rstrip("-")
    return slug or fallback
