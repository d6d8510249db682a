"""Reading and writing `.npz` archives of named arrays (never with pickle)."""

from __future__ import annotations

import io
import math
import zipfile
from typing import IO

import numpy as np
from numpy.lib import format as npy_format

from service.problems import Unprocessable
from service.settings import Settings
from service.sizes import check_array_elements, first_too_large, request_memory_issues

NUMERIC_KINDS = "biuf"
"""dtype kinds an uploaded array may have: booleans, integers, floats (never void, bytes or text)."""
NPZ_EXPANSION = 6
"""Peak memory of reading and validating an MDP's arrays, per byte the members declare (measured: 256 MB of
next_state took 1.4 GB)."""
MAX_MEMBERS = 16
"""Most arrays one uploaded `.npz` may hold."""


def _unreadable(pointer: str, why: object) -> Unprocessable:
    """422: the file is not a readable pickle-free `.npz`."""
    return Unprocessable(
        "The uploaded file is not a readable .npz archive.",
        errors=[{"pointer": pointer, "message": f"is not a readable .npz archive without pickles ({why})"}],
    )


def npz_headers(
    file: IO[bytes], *, pointer: str, settings: Settings
) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Each member's (shape, dtype) from its `.npy` header alone, nothing else read or decompressed; 422 if
    the archive is unreadable, holds more than `MAX_MEMBERS` arrays, an object (pickled) array, or an array
    of more than `max_array_elements` elements, one that is not of numbers or booleans, or arrays that would
    take more than ``api_max_request_memory_mb`` together (× `NPZ_EXPANSION`). Leaves `file` at its start."""
    headers: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    try:
        with zipfile.ZipFile(file) as archive:
            members = [m for m in archive.infolist() if not m.is_dir()]
            if len(members) > MAX_MEMBERS:
                raise Unprocessable(
                    f"The .npz holds {len(members)} arrays; at most {MAX_MEMBERS}.",
                    errors=[
                        {"pointer": pointer, "message": f"holds {len(members)} arrays; at most {MAX_MEMBERS}"}
                    ],
                )
            for member in members:
                name = member.filename.removesuffix(".npy")
                with archive.open(member) as handle:
                    version = npy_format.read_magic(handle)
                    if version == (1, 0):
                        shape, _fortran, dtype = npy_format.read_array_header_1_0(handle)
                    elif version == (2, 0):
                        shape, _fortran, dtype = npy_format.read_array_header_2_0(handle)
                    else:
                        raise _unreadable(pointer, f"array {name!r} uses .npy format version {version}")
                if dtype.hasobject:
                    raise _unreadable(pointer, f"array {name!r} holds Python objects")
                if dtype.kind not in NUMERIC_KINDS:
                    raise _unreadable(
                        pointer, f"array {name!r} has dtype {dtype.str}, not numbers or booleans"
                    )
                check_array_elements(name, shape, settings, pointer=pointer)
                headers[name] = (tuple(int(d) for d in shape), dtype)
            declared = sum(math.prod(shape) * dtype.itemsize for shape, dtype in headers.values())
            first_too_large(
                request_memory_issues(
                    "reading and checking the .npz's arrays",
                    declared * NPZ_EXPANSION,
                    settings,
                    pointer=pointer,
                )
            )
    except (ValueError, OSError, zipfile.BadZipFile, EOFError, KeyError) as exc:
        raise _unreadable(pointer, exc) from exc
    finally:
        file.seek(0)
    return headers


def read_npz(file: IO[bytes], *, pointer: str, settings: Settings | None = None) -> dict[str, np.ndarray]:
    """All arrays of an uploaded `.npz`; 422 at `pointer` if it is not a readable pickle-free archive, and
    (with `settings`) before reading anything if a member's header shows it too large (`npz_headers`)."""
    if settings is not None:
        npz_headers(file, pointer=pointer, settings=settings)
    try:
        with np.load(file, allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError, KeyError) as exc:
        raise _unreadable(pointer, exc) from exc


def write_npz(arrays: dict[str, np.ndarray]) -> bytes:
    """An uncompressed `.npz` archive of `arrays` (fast to write for 80,000-state MDPs)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()
