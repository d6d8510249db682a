"""C3D uploads: recognise the format and read the force platforms in a child process (`c3d_reader`).

ezc3d's parser is C++ that can crash (SIGSEGV) or loop on a malformed file, so the API never loads it: the
file goes to ``python -m service.files.c3d_reader`` with a time limit (`TIMEOUT_S`) and a memory limit, and
every way that process fails on a bad file becomes a 422 naming the file.
"""

from __future__ import annotations

import io
import json
import os
import struct
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from service.files.c3d_reader import UNREADABLE
from service.problems import Unprocessable

READER = ("-m", "service.files.c3d_reader")
"""The Python arguments that run the reader (the file's path is appended)."""
TIMEOUT_S = 60.0
"""Longest a C3D may take to read; a longer read is stopped and the upload refused."""
MAGIC = 0x50
"""The second byte of every C3D file (its first is the parameter block's number)."""


@dataclass(frozen=True)
class Platform:
    """One force platform as ezc3d computed it: (3, N) force and COP in the lab frame, (3, 4) corners."""

    force: np.ndarray
    center_of_pressure: np.ndarray
    corners: np.ndarray
    position_unit: str
    force_unit: str


@dataclass(frozen=True)
class C3dFile:
    """What a C3D upload holds for a recording: its force platforms, analog rate, time origin and events."""

    platforms: list[Platform]
    analog_rate: float
    analog_rate_source: str
    """Where the rate came from: the ``header`` or, where the header's is 0, ``ANALOG:RATE``."""
    start_s: float
    """Time of the first analog sample: the first frame's, counted from frame 1 as the events' times are."""
    events: list[tuple[str, float]]
    """(label, time in seconds) of every event of the EVENT group, in file order."""


def is_c3d(data: bytes) -> bool:
    """Whether `data` starts as a C3D file does: a parameter-block number (a control byte), then 0x50."""
    return len(data) >= 2 and 0 < data[0] < 0x20 and data[1] == MAGIC


def declared_size(data: bytes) -> int | None:
    """Bytes a C3D needs for the frames its header declares (header words 2–5 and 9, the scale factor's sign
    for 2- or 4-byte samples, byte order from the parameter block's processor type); None where the header
    cannot say (no parameter block, no samples declared)."""
    block = (data[0] - 1) * 512
    if len(data) < max(block + 4, 18):
        return None
    processor = data[block + 3] - 83  # 1 Intel, 2 DEC, 3 MIPS (big-endian)
    order = ">" if processor == 3 else "<"
    points, analogs, first, last = struct.unpack(order + "4H", data[2:10])
    start = struct.unpack(order + "H", data[16:18])[0]
    if points + analogs == 0 or start == 0 or last < first:
        return None
    sign_byte = {2: 13, 3: 12}.get(processor, 15)  # where the float's sign bit lies: DEC, big-endian, IEEE LE
    sample = 4 if data[sign_byte] & 0x80 else 2
    return (start - 1) * 512 + (last - first + 1) * (4 * points + analogs) * sample


def file_problem(message: str) -> Unprocessable:
    """A 422 about the uploaded file as a whole."""
    return Unprocessable(f"The file is invalid: {message}", errors=[{"pointer": "/file", "message": message}])


def read_c3d(data: bytes) -> C3dFile:
    """Read a C3D upload's force platforms in a child process; 422 if it is not a C3D ezc3d can read."""
    if not is_c3d(data):
        raise file_problem(f"is not a C3D file (a C3D's second byte is 0x{MAGIC:02X})")
    needed = declared_size(data)
    if needed is not None and len(data) < needed:
        raise file_problem(
            f"is truncated: its header declares frames that need {needed} bytes, the file has {len(data)}"
        )
    with tempfile.TemporaryDirectory(prefix="metairl-c3d-") as folder:
        path = Path(folder) / "upload.c3d"
        path.write_bytes(data)
        env = os.environ | {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
        try:
            done = subprocess.run(
                [sys.executable, *READER, str(path)], capture_output=True, timeout=TIMEOUT_S, env=env
            )
        except subprocess.TimeoutExpired as exc:
            raise file_problem(f"reading the C3D took longer than {TIMEOUT_S:g} s; it is malformed") from exc
    if done.returncode == UNREADABLE:
        failure = json.loads(done.stdout)
        if failure["stage"] == "file":
            raise file_problem(f"is not a readable C3D file ({failure['message']})")
        raise file_problem(f"its FORCE_PLATFORM parameters or channels cannot be used ({failure['message']})")
    if done.returncode < 0:
        raise file_problem(f"the C3D reader stopped on signal {-done.returncode} reading it; it is malformed")
    if done.returncode != 0:
        raise RuntimeError(
            f"the C3D reader failed (exit status {done.returncode}): {done.stderr.decode()[-2000:]}"
        )
    return _parsed(done.stdout)


def _parsed(output: bytes) -> C3dFile:
    """The reader's ``.npz`` output as a `C3dFile`."""
    with np.load(io.BytesIO(output), allow_pickle=False) as npz:
        meta = json.loads(str(npz["meta"]))
        platforms = [
            Platform(
                force=npz[f"force_{k}"],
                center_of_pressure=npz[f"center_of_pressure_{k}"],
                corners=npz[f"corners_{k}"],
                position_unit=units["position_unit"],
                force_unit=units["force_unit"],
            )
            for k, units in enumerate(meta["platforms"])
        ]
    return C3dFile(
        platforms=platforms,
        analog_rate=meta["analog_rate"],
        analog_rate_source=meta["analog_rate_source"],
        start_s=meta["first_frame"] / meta["point_rate"] if meta["point_rate"] > 0 else 0.0,
        events=[(e["label"], e["time"]) for e in meta["events"]],
    )
