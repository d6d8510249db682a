"""Read a C3D file's force platforms with ezc3d, in a child process of the API (`service.files.c3d` runs it).

``python -m service.files.c3d_reader FILE`` writes an ``.npz`` to stdout: per platform ``force_k``,
``center_of_pressure_k`` (3, N) and ``corners_k`` (3, 4) in the file's units, and ``meta``, a JSON string with
the units, rates, first frame and events. ezc3d's C++ parser can crash or hang on a malformed file, so it runs
here, under a memory limit, and never in the API process; a file it rejects exits with `UNREADABLE` and a
JSON ``{"stage", "message"}`` on stdout. ezc3d is imported in `read`, so importing this module never loads it.
"""

from __future__ import annotations

import io
import json
import resource
import sys
from typing import Any

import numpy as np

UNREADABLE = 3
"""Exit status for a file ezc3d rejected (an exception, not a crash)."""
MEMORY_LIMIT_BYTES = 4 * 1024**3
"""Address space the reader may use, so a file claiming huge sizes fails to read instead of exhausting memory."""


class ReadError(Exception):
    """ezc3d rejected the file (`stage` ``file``) or only its FORCE_PLATFORM parameters (``platform``)."""

    def __init__(self, stage: str, message: str):
        super().__init__(message)
        self.stage, self.message = stage, message


def _events(parameters: Any) -> list[dict[str, Any]]:
    """The EVENT group's events as {label, time} (time in seconds from frame 1), in file order."""
    group = parameters.get("EVENT", {})
    if "LABELS" not in group or "TIMES" not in group:
        return []
    labels = list(group["LABELS"]["value"])
    times = np.asarray(group["TIMES"]["value"], dtype=np.float64).reshape(2, -1)
    used = int(np.asarray(group["USED"]["value"]).ravel()[0]) if "USED" in group else len(labels)
    return [
        {"label": labels[k], "time": 60 * times[0, k] + times[1, k]}
        for k in range(min(used, len(labels), times.shape[1]))
    ]


def _parameter_rate(parameters: Any) -> float:
    """ANALOG:RATE, where a writer that leaves the header's analog rate 0 (Kistler's) keeps it; 0 if absent."""
    value = np.asarray(
        parameters.get("ANALOG", {}).get("RATE", {}).get("value", []), dtype=np.float64
    ).ravel()
    return float(value[0]) if value.size and np.isfinite(value[0]) else 0.0


def read(path: str) -> bytes:
    """The platforms and metadata of the C3D at `path` as ``.npz`` bytes; `ReadError` if ezc3d rejects it."""
    import ezc3d

    failures = (RuntimeError, ValueError, OSError, IndexError, KeyError, MemoryError)
    try:
        c3d = ezc3d.c3d(path, extract_forceplat_data=True)
    except failures as exc:
        try:
            ezc3d.c3d(path)
        except failures as plain:
            raise ReadError("file", str(plain) or type(plain).__name__) from plain
        raise ReadError("platform", str(exc) or type(exc).__name__) from exc
    header, platforms = c3d["header"], c3d["data"]["platform"]
    rate, rate_source = float(header["analogs"]["frame_rate"]), "header"
    if rate <= 0:
        rate, rate_source = _parameter_rate(c3d["parameters"]), "ANALOG:RATE"
    meta = {
        "analog_rate": rate,
        "analog_rate_source": rate_source,
        "point_rate": float(header["points"]["frame_rate"]),
        "first_frame": int(header["points"]["first_frame"]),
        "events": _events(c3d["parameters"]),
        "platforms": [
            {"position_unit": p["unit_position"], "force_unit": p["unit_force"]} for p in platforms
        ],
    }
    arrays: dict[str, np.ndarray] = {"meta": np.array(json.dumps(meta))}
    for k, p in enumerate(platforms):
        arrays |= {
            f"force_{k}": np.asarray(p["force"], dtype=np.float64),
            f"center_of_pressure_{k}": np.asarray(p["center_of_pressure"], dtype=np.float64),
            f"corners_{k}": np.asarray(p["corners"], dtype=np.float64),
        }
    out = io.BytesIO()  # not service.files.npz: it loads FastAPI and SQLAlchemy, a second per upload here
    np.savez(out, **arrays)  # type: ignore[arg-type]
    return out.getvalue()


def main(argv: list[str]) -> int:
    """Limit memory, read ``argv[0]`` and write the result (or the reason it failed) to stdout."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))
    try:
        result = read(argv[0])
    except ReadError as exc:
        sys.stdout.write(json.dumps({"stage": exc.stage, "message": exc.message}))
        return UNREADABLE
    sys.stdout.buffer.write(result)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
