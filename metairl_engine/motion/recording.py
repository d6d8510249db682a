"""From raw centre-of-pressure (COP) recordings to velocity-grid demonstrations (paper §IV-B).

numpy only (scipy's peak finder is imported when segmenting). The pipeline is
`Recording.build` (validate) → `discretise` (samples → an 8-connected walk of grid cells, skipped cells
filled, pauses dropped) → `segment` (out-and-back movements split at peaks of the distance from the
origin, labelled by instruction or direction) → `demonstrations` ({label: [Trajectory, ...]} valid on
``grid_mdp(width, height, velocity=True)``). Directions and their clinical names are `grids.DIRECTIONS`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from metairl_engine.demos import Trajectory
from metairl_engine.errors import InvalidInput, Issue, check
from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS, direction_index, velocity_state
from metairl_engine.mdp import MAX_ISSUES

NO_INSTRUCTION = ""
"""The instruction of a sample taken while no direction was instructed."""


@dataclass(frozen=True)
class Bounds:
    """The force plate's rectangle in the recording's units (e.g. metres); the grid covers exactly this."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    @property
    def centre(self) -> tuple[float, float]:
        """The middle of the plate: the default origin of out-and-back movements."""
        return (self.x_min + self.x_max) / 2, (self.y_min + self.y_max) / 2

    def issues(self, pointer: str = "/bounds") -> list[Issue]:
        """Non-finite values or empty ranges."""
        out = [
            Issue(f"{pointer}/{name}", "must be a finite number")
            for name in ("x_min", "x_max", "y_min", "y_max")
            if not (isinstance(getattr(self, name), int | float) and np.isfinite(getattr(self, name)))
        ]
        if not out:
            for axis in ("x", "y"):
                lo, hi = getattr(self, f"{axis}_min"), getattr(self, f"{axis}_max")
                if not lo < hi:
                    out.append(
                        Issue(f"{pointer}/{axis}_max", f"must be greater than {axis}_min = {lo}, got {hi}")
                    )
        return out


@dataclass(frozen=True, eq=False)
class Recording:
    """A validated COP recording: ``t``, ``x``, ``y`` (N,) float64 with strictly increasing ``t``, all
    samples inside ``bounds``; ``instruction`` (N,) str (`NO_INSTRUCTION` where none) or None."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    bounds: Bounds
    instruction: np.ndarray | None = None

    @classmethod
    def build(
        cls,
        *,
        t: Sequence[float] | np.ndarray,
        x: Sequence[float] | np.ndarray,
        y: Sequence[float] | np.ndarray,
        bounds: Bounds,
        instruction: Sequence[str | None] | np.ndarray | None = None,
        labels: Sequence[str] = DIRECTION_NAMES,
        min_samples: int = 2,
    ) -> Recording:
        """Coerce and validate; raises `InvalidInput` with pointers like ``/samples/17/t``.

        Instructions are read by `canonical_instruction` (``forward_left``, ``Forward-Left`` and ``forward
        left`` are the same; ``rest``, ``none``, empty or None mean no instruction) and must then be one of
        ``labels``. Every issue names its sample; they come in sample order.
        """
        issues = bounds.issues()
        columns: dict[str, np.ndarray] = {}
        for name, raw in (("t", t), ("x", x), ("y", y)):
            try:
                columns[name] = np.asarray(raw, dtype=np.float64)
            except (TypeError, ValueError):
                issues.append(Issue("/samples", f"column {name} must hold numbers"))
        check(issues)
        lengths = {name: col.shape for name, col in columns.items()}
        if instruction is not None:
            lengths["instruction"] = np.asarray(instruction, dtype=object).shape
        if any(len(shape) != 1 for shape in lengths.values()) or len(set(lengths.values())) != 1:
            check(
                [Issue("/samples", f"t, x, y (and instruction) must be flat and equally long, got {lengths}")]
            )
        n = len(columns["t"])
        if n < min_samples:
            what = "is empty" if n == 0 else f"has {n} sample{'s' * (n != 1)}"
            check([Issue("/samples", f"{what}; a recording needs at least {min_samples} samples")])
        found = _sample_issues(columns, bounds)
        labels_out = None
        if instruction is not None:
            labels_out, unknown = _instruction_labels(instruction, labels)
            found += unknown
        found.sort(key=lambda item: item[0])  # stable: per sample, columns in t, x, y, instruction order
        check(issues + [issue for _, issue in found[:MAX_ISSUES]])
        return cls(t=columns["t"], x=columns["x"], y=columns["y"], bounds=bounds, instruction=labels_out)

    @property
    def sample_rate(self) -> float:
        """Samples per time unit (`sampling_rate`)."""
        return sampling_rate(self.t)


GAP_FACTOR = 1.5
"""An interval this many times the median one is a gap (samples missing): `sampling_rate` then uses the median."""


def sampling_rate(t: np.ndarray) -> float:
    """Samples per second of increasing times ``t``: (N − 1) / (t[-1] − t[0]) in float64, which averages out
    the rounding of stored times (float32 steps bias a median interval, by 4e-4 at 2000 Hz); the median
    interval's inverse when some interval exceeds `GAP_FACTOR` times it (samples missing), since the span would
    count time that was not sampled."""
    t = np.asarray(t, dtype=np.float64)
    dt = np.diff(t)
    median = float(np.median(dt))
    rounding = 2 * float(np.finfo(np.float32).eps) * float(max(abs(t[0]), abs(t[-1])))  # float32 storage
    if float(dt.max()) > GAP_FACTOR * median + rounding:
        return 1.0 / median
    return (len(t) - 1) / float(t[-1] - t[0])


def _sample_issues(columns: dict[str, np.ndarray], bounds: Bounds) -> list[tuple[int, Issue]]:
    """Non-finite values, non-increasing times and samples off the plate, as (sample, issue) in sample order."""
    found: list[tuple[int, str, str]] = []
    for name, col in columns.items():
        found += [
            (int(k), name, "must be a finite number (no NaN or infinity)")
            for k in np.flatnonzero(~np.isfinite(col))[:MAX_ISSUES]
        ]
    t = columns["t"]
    finite_t = np.isfinite(t)
    for k in np.flatnonzero(~(t[1:] > t[:-1]) & finite_t[1:] & finite_t[:-1])[:MAX_ISSUES]:
        found.append(
            (
                int(k) + 1,
                "t",
                f"time {t[k + 1]:g} is not after the previous sample's {t[k]:g}: times must strictly increase",
            )
        )
    for name, lo, hi in (("x", bounds.x_min, bounds.x_max), ("y", bounds.y_min, bounds.y_max)):
        col = columns[name]
        for k in np.flatnonzero(np.isfinite(col) & ((col < lo) | (col > hi)))[:MAX_ISSUES]:
            found.append((int(k), name, f"{name} = {col[k]:g} is outside the plate [{lo:g}, {hi:g}]"))
    order = {"t": 0, "x": 1, "y": 2}
    found.sort(key=lambda item: (item[0], order[item[1]]))
    return [(k, Issue(f"/samples/{k}/{name}", message)) for k, name, message in found[:MAX_ISSUES]]


REST_SPELLINGS = frozenset({"", "rest", "none", "no instruction", "null", "nan"})
"""Instruction values (after `canonical_instruction`'s normalisation) that mean "no instruction"."""


def canonical_instruction(value: object) -> str:
    """An uploaded instruction in canonical spelling: lower case, ``_`` and ``-`` read as spaces, runs of
    spaces collapsed (``Forward_Left`` → ``forward left``); rest spellings (`REST_SPELLINGS`, None, NaN)
    become `NO_INSTRUCTION`. Whether the result is a known direction is the caller's check."""
    if value is None or (isinstance(value, float) and value != value):
        return NO_INSTRUCTION
    text = " ".join(str(value).replace("_", " ").replace("-", " ").lower().split())
    return NO_INSTRUCTION if text in REST_SPELLINGS else text


def _instruction_labels(
    instruction: Sequence[str | None] | np.ndarray, labels: Sequence[str]
) -> tuple[np.ndarray, list[tuple[int, Issue]]]:
    """Canonical instruction strings (N,) and, for each unknown value, (its first sample, an issue)."""
    known = {canonical_instruction(label): label for label in labels}
    raw = np.array(["" if v is None else str(v) for v in instruction], dtype=str)
    values, first, inverse = np.unique(raw, return_index=True, return_inverse=True)
    names = [canonical_instruction(str(v)) for v in values]
    mapped = [NO_INSTRUCTION if n == NO_INSTRUCTION else known.get(n) for n in names]
    found = [
        (
            int(k),
            Issue(
                f"/samples/{int(k)}/instruction",
                f"unknown instruction {str(v)!r}; use one of {', '.join(labels)} (words joined by spaces, "
                "_ or -, any case), or rest, none or empty for no instruction",
            ),
        )
        for v, k, m in zip(values, first, mapped, strict=True)
        if m is None
    ]
    found.sort(key=lambda item: item[0])
    table = np.array([NO_INSTRUCTION if m is None else m for m in mapped] or [NO_INSTRUCTION], dtype=object)
    return table[inverse.reshape(-1)].astype(str), found[:MAX_ISSUES]


@dataclass(frozen=True)
class DiscretiseSettings:
    """How COP samples become grid cells: a ``width`` × ``height`` grid over the plate bounds."""

    width: int = 100
    height: int = 100
    smooth_s: float = 0.05
    """Moving-average window (in the recording's time unit) applied to x and y before binning, so sensor
    noise does not flicker across cell borders; 0 turns smoothing off."""

    def issues(self, pointer: str = "/discretise") -> list[Issue]:
        """Unusable settings."""
        out = [
            Issue(f"{pointer}/{name}", f"must be an integer ≥ 2, got {value!r}")
            for name, value in (("width", self.width), ("height", self.height))
            if not isinstance(value, int) or value < 2
        ]
        if not (np.isfinite(self.smooth_s) and self.smooth_s >= 0):
            out.append(Issue(f"{pointer}/smooth_s", f"must be ≥ 0, got {self.smooth_s!r}"))
        return out


@dataclass(frozen=True, eq=False)
class CellPath:
    """A recording as a walk of 8-connected grid cells, each step one king move.

    ``x``, ``y`` (M,) int64 cells; ``direction`` (M,) int64 index into `DIRECTIONS` of the move that
    entered each cell (the first cell takes its leaving move's); ``sample`` (M,) the sample that reached it.
    """

    x: np.ndarray
    y: np.ndarray
    direction: np.ndarray
    sample: np.ndarray
    width: int
    height: int

    def trajectory(self, start: int = 0, stop: int | None = None) -> Trajectory:
        """Cells ``start:stop`` as a velocity-grid trajectory: states (T+1,) and actions (T,), T ≥ 1."""
        stop = len(self.x) if stop is None else stop
        if stop - start < 2:
            raise ValueError(f"cells {start}:{stop} hold no move")
        states = velocity_state(
            self.x[start:stop],
            self.y[start:stop],
            self.direction[start:stop],
            width=self.width,
            height=self.height,
        )
        return Trajectory.of(states, self.direction[start + 1 : stop])


def grid_cells(rec: Recording, settings: DiscretiseSettings) -> tuple[np.ndarray, np.ndarray]:
    """The (smoothed) cell (x, y) of every sample: two (N,) int64 arrays."""
    b = rec.bounds
    window = _odd_window(settings.smooth_s * rec.sample_rate)
    cells = []
    for values, lo, hi, n in (
        (rec.x, b.x_min, b.x_max, settings.width),
        (rec.y, b.y_min, b.y_max, settings.height),
    ):
        scaled = (_moving_average(values, window) - lo) / (hi - lo) * n
        cells.append(np.clip(np.floor(scaled), 0, n - 1).astype(np.int64))
    return cells[0], cells[1]


def discretise(rec: Recording, settings: DiscretiseSettings = DiscretiseSettings()) -> CellPath:
    """The recording's walk over grid cells: pauses dropped, jumps filled along a straight 8-connected line."""
    check(settings.issues())
    cx, cy = grid_cells(rec, settings)
    changed = np.flatnonzero(np.r_[True, (cx[1:] != cx[:-1]) | (cy[1:] != cy[:-1])])
    cx, cy = cx[changed], cy[changed]
    if len(changed) < 2:
        check(
            [
                Issue(
                    "/samples",
                    f"the COP never leaves one cell of the {settings.width}×{settings.height} grid",
                )
            ]
        )
    dx, dy = np.diff(cx), np.diff(cy)
    steps = np.maximum(np.abs(dx), np.abs(dy))  # ≥ 1: consecutive cells differ
    jump = np.repeat(np.arange(len(steps)), steps)
    i = np.arange(len(jump)) - np.repeat(np.cumsum(steps) - steps, steps) + 1  # 1..steps within each jump
    px = cx[jump] + np.floor(i * dx[jump] / steps[jump] + 0.5).astype(np.int64)
    py = cy[jump] + np.floor(i * dy[jump] / steps[jump] + 0.5).astype(np.int64)
    x, y = np.r_[cx[0], px], np.r_[cy[0], py]
    entered = direction_index(np.diff(x), np.diff(y))
    return CellPath(
        x=x,
        y=y,
        direction=np.r_[entered[0], entered],
        sample=np.r_[changed[0], changed[1:][jump]],
        width=settings.width,
        height=settings.height,
    )


def _odd_window(samples: float) -> int:
    """``samples`` rounded to an odd window length (at least 1)."""
    n = max(round(samples), 1)
    return n if n % 2 else n + 1


def _moving_average(values: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average of odd length ``window``, edges padded with the end values; same length."""
    if window <= 1:
        return values
    padded = np.pad(values, window // 2, mode="edge")
    return np.convolve(padded, np.full(window, 1.0 / window), mode="valid")


@dataclass(frozen=True)
class SegmentSettings:
    """How a session splits into out-and-back movements (peaks of distance from ``origin``)."""

    origin: tuple[float, float] | None = None
    """Where movements start and end, in plate units; None means the plate centre."""
    min_prominence: float = 0.3
    """A peak must rise this fraction of the session's largest distance above its surroundings."""
    min_separation_s: float = 0.5
    """Peaks closer than this (in the recording's time unit) count as one movement."""
    smooth_s: float = 0.1
    """Moving-average window applied to the distance before peak finding (0: off)."""
    label_fraction: float = 0.5
    """A segment's instruction is the majority over its samples at least this fraction of its peak distance
    away from the origin: the movement itself, not the rests around it (which may belong to the next one)."""
    directions: tuple[str, ...] = DIRECTION_NAMES
    """Labels available when a segment has no instruction: the nearest of these directions to the peak."""

    def issues(self, pointer: str = "/segment") -> list[Issue]:
        """Unusable settings."""
        out = []
        for name in ("min_prominence", "label_fraction"):
            if not 0 < getattr(self, name) < 1:
                out.append(Issue(f"{pointer}/{name}", f"must be in (0, 1), got {getattr(self, name)!r}"))
        for name in ("min_separation_s", "smooth_s"):
            if not getattr(self, name) >= 0:
                out.append(Issue(f"{pointer}/{name}", f"must be ≥ 0, got {getattr(self, name)!r}"))
        unknown = [d for d in self.directions if d not in DIRECTION_NAMES]
        if unknown or not self.directions:
            found = f" ({', '.join(map(repr, unknown))} is not one)" if unknown else ""
            out.append(Issue(f"{pointer}/directions", f"must be some of {', '.join(DIRECTION_NAMES)}{found}"))
        return out


@dataclass(frozen=True)
class Segment:
    """One out-and-back movement: samples ``start:stop``, its farthest sample ``peak`` and its ``label``."""

    start: int
    stop: int
    peak: int
    label: str


def segment(rec: Recording, settings: SegmentSettings = SegmentSettings()) -> list[Segment]:
    """Split at the distance minima between prominent distance peaks; label each part (see `SegmentSettings`).

    A segment runs from the minimum before its peak to the minimum after it (the recording's ends for the
    first and last); without instructions it is named by the nearest allowed direction to its peak.
    """
    from scipy.signal import find_peaks  # only here: keeps `import metairl_engine.motion.recording` light

    check(settings.issues())
    ox, oy = rec.bounds.centre if settings.origin is None else settings.origin
    distance = _moving_average(
        np.hypot(rec.x - ox, rec.y - oy), _odd_window(settings.smooth_s * rec.sample_rate)
    )
    peaks, _ = find_peaks(
        distance,
        prominence=settings.min_prominence * float(distance.max()),
        distance=max(1, round(settings.min_separation_s * rec.sample_rate)),
    )
    cuts = [0] + [int(a + np.argmin(distance[a:b])) for a, b in pairwise(peaks)] + [len(distance)]
    wanted = np.array([DIRECTION_NAMES.index(d) for d in settings.directions])
    out = []
    for k, peak in enumerate(peaks):
        start, stop = cuts[k], cuts[k + 1]
        far = start + np.flatnonzero(distance[start:stop] >= settings.label_fraction * distance[peak])
        label = _majority(rec.instruction[far]) if rec.instruction is not None else NO_INSTRUCTION
        if label == NO_INSTRUCTION:
            heading = np.array([rec.x[peak] - ox, rec.y[peak] - oy])
            unit = DIRECTIONS[wanted] / np.hypot(DIRECTIONS[wanted, 0], DIRECTIONS[wanted, 1])[:, None]
            label = DIRECTION_NAMES[int(wanted[np.argmax(unit @ heading)])]
        out.append(Segment(start=start, stop=stop, peak=int(peak), label=label))
    return out


def _majority(labels: np.ndarray) -> str:
    """The most frequent instruction among ``labels`` ignoring `NO_INSTRUCTION` (which it returns if all are)."""
    given = labels[labels != NO_INSTRUCTION]
    if given.size == 0:
        return NO_INSTRUCTION
    values, counts = np.unique(given, return_counts=True)
    return str(values[np.argmax(counts)])


@dataclass(frozen=True, eq=False)
class Demonstrations:
    """A session cut into labelled trajectories: ``by_label`` {label: [Trajectory, ...]} in time order,
    the ``segments`` they came from (same order, flattened) and the ``path`` they were cut from."""

    by_label: dict[str, list[Trajectory]]
    segments: list[Segment]
    path: CellPath
    dropped: list[Segment] = field(default_factory=list)
    """Segments that never left their first cell (no move to learn from)."""


def demonstrations(
    rec: Recording,
    *,
    discretise_settings: DiscretiseSettings = DiscretiseSettings(),
    segment_settings: SegmentSettings = SegmentSettings(),
) -> Demonstrations:
    """Discretise, segment and cut: every trajectory is valid on the ``velocity=True`` grid of that size.

    Raises `InvalidInput` when no segment moves (nothing to learn from).
    """
    path = discretise(rec, discretise_settings)
    by_label: dict[str, list[Trajectory]] = {}
    kept, dropped = [], []
    for seg in segment(rec, segment_settings):
        first, last = np.searchsorted(path.sample, [seg.start, seg.stop])
        if last - first < 2:
            dropped.append(seg)
            continue
        by_label.setdefault(seg.label, []).append(path.trajectory(int(first), int(last)))
        kept.append(seg)
    if not kept:
        raise InvalidInput([Issue("/samples", "holds no out-and-back movement that leaves its grid cell")])
    return Demonstrations(by_label=by_label, segments=kept, path=path, dropped=dropped)
