"""What a standing upload makes of every C3D in ``../shared/data/c3d``: per file and per force platform, the
sway measures of the recording it gives, or the 422 and its reason; then a copy cut to half its bytes.

Run: ``python -m benchmarks.standing_corpus`` (from the repository root). The same path as the upload route
(`service.files.force_plates.file_samples` with ``protocol="standing"``, `standing_recording`, then the sway
measures), without the database; tests/service/test_standing.py checks the same through HTTP.
"""

from __future__ import annotations

import sys
from pathlib import Path

from metairl_engine.motion.sway import sway_measures
from service.domain.recordings import PlateIn, RecordingOptions
from service.files.c3d import read_c3d
from service.files.force_plates import file_samples
from service.problems import Unprocessable
from service.store.recordings import standing_recording

CORPUS = Path(__file__).resolve().parent.parent.parent / "shared" / "data" / "c3d"


def outcome(name: str, data: bytes, platform: int | None) -> str:
    """One line: the recording's size and contract measures, or the 422's pointer and message."""
    try:
        samples = file_samples(name, data, PlateIn(platform=platform), "standing")
        rec = standing_recording(RecordingOptions(protocol="standing"), samples)
        m = sway_measures(rec.t, rec.x, rec.y)
    except Unprocessable as exc:
        error = exc.errors[0] if exc.errors else {"pointer": "", "message": str(exc)}
        return f"422 {error['pointer']}: {error['message']}"
    plate = samples.plate or {}
    return (
        f"recording: platform {plate.get('platform')} ({plate.get('platform_choice')}), {m.n_samples} samples "
        f"at {m.rate_hz:g} Hz ({plate.get('rate_source')}), unit {plate.get('position_unit')!r} as "
        f"{plate.get('position_unit_read_as')}, {plate.get('n_events')} events {plate.get('events')}, "
        f"{len(plate.get('loaded_stretches_dropped', []))} other loaded stretches dropped; area95 "
        f"{m.area95 * 1e4:.3g} cm², mean_velocity {m.mean_velocity * 100:.3g} cm/s, mean_frequency "
        f"{m.mean_frequency:.3g} Hz{' (coarse: under 20 s)' if 'mean_frequency' in m.caveats else ''}"
    )


def platforms_of(data: bytes) -> int:
    """How many force platforms the file has (0 when unreadable)."""
    try:
        return len(read_c3d(data).platforms)
    except Unprocessable:
        return 0


def main() -> int:
    """Print every file's outcome: without `plate.platform`, then with each platform, then cut in half."""
    if not CORPUS.exists():
        print(f"{CORPUS} is absent", file=sys.stderr)
        return 1
    for path in sorted(CORPUS.iterdir()):
        data = path.read_bytes()
        print(f"{path.name}:")
        print(f"  default: {outcome(path.name, data, None)}")
        for k in range(1, platforms_of(data) + 1):
            print(f"  platform {k}: {outcome(path.name, data, k)}")
        print(f"  half of its bytes: {outcome(path.name, data[: len(data) // 2], None)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
