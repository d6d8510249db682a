"""Kinematic readout of COP recordings: the descriptors posturography uses, per instructed direction.

numpy only (scipy's peak finder through `motion.segment`; matplotlib only inside `comparison_png`). This is
the readout a clinician checks the learned rewards against (docs/api.md, "Motion readout"): from the out-and-back movements that
`motion.segment` finds, per movement

- ``peak_reach``: the farthest the COP got along the instructed direction, from where the movement started;
- ``path_length``: the length of the COP path from movement onset to its end (out and back);
- ``deviation``: the mean distance of the COP from the instructed line (through the start, along the
  instructed direction) from onset to end;
- ``time_to_peak_s``: time from movement onset to the farthest point;
- ``mean_speed``: path length over the movement's duration;

all lengths in the units of the uploaded x, y, times in those of t. A movement starts where the COP rests
before it (the mean of the segment's first ``rest_s``); its onset is the first sample farther from there than
``onset_fraction`` of its peak distance, its end the last such sample. Per direction, every descriptor is
summarised by its mean over repetitions with a 95 % percentile-bootstrap interval over repetitions (seeded,
``scipy.stats.bootstrap`` through `motion.bootstrap`, scipy imported when an interval is drawn); `compare`
gives b minus a per direction with intervals from resampling both sides.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS
from metairl_engine.motion.bootstrap import percentile_interval
from metairl_engine.motion.recording import Recording, SegmentSettings, segment

if TYPE_CHECKING:
    from matplotlib.figure import Figure

DESCRIPTORS = ("peak_reach", "path_length", "deviation", "time_to_peak_s", "mean_speed")
"""Descriptor names, in the order the readout lists them (docs/api.md, "Motion readout")."""

LENGTHS = frozenset({"peak_reach", "path_length", "deviation"})
"""Descriptors in the units of x, y (``mean_speed`` is in those units per time unit, the others in time units)."""


@dataclass(frozen=True)
class KinematicSettings:
    """How movements are measured (times in the recording's time unit)."""

    smooth_s: float = 0.05
    """Moving-average window applied to x and y first, so sensor noise does not inflate the path length."""
    rest_s: float = 0.1
    """The movement's start position is the mean COP over the segment's first ``rest_s``."""
    onset_fraction: float = 0.1
    """The movement runs while the COP is farther than this fraction of its peak distance from the start."""
    n_boot: int = 2000
    """Bootstrap resamples per interval."""
    seed: int = 0
    """Seed of the bootstrap: same recordings and seed, same intervals."""


@dataclass(frozen=True)
class Movement:
    """One movement's descriptors (see the module docstring) and its label (a `DIRECTION_NAMES` entry)."""

    direction: str
    peak_reach: float
    path_length: float
    deviation: float
    time_to_peak_s: float
    mean_speed: float

    def value(self, name: str) -> float:
        """The descriptor ``name`` (one of `DESCRIPTORS`)."""
        return float(getattr(self, name))


def _unit(direction: str) -> np.ndarray:
    d = DIRECTIONS[DIRECTION_NAMES.index(direction)].astype(np.float64)
    return d / np.hypot(d[0], d[1])


def _smooth(values: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average of odd length ``window`` (edges padded with the end values)."""
    if window <= 1:
        return values
    padded = np.pad(values, window // 2, mode="edge")
    return np.convolve(padded, np.full(window, 1.0 / window), mode="valid")


def movements(
    rec: Recording,
    *,
    segment_settings: SegmentSettings = SegmentSettings(),
    settings: KinematicSettings = KinematicSettings(),
) -> list[Movement]:
    """The descriptors of every out-and-back movement `motion.segment` finds in ``rec``, in time order."""
    rate = rec.sample_rate
    window = max(round(settings.smooth_s * rate), 1) | 1
    x, y = _smooth(rec.x, window), _smooth(rec.y, window)
    out = []
    for seg in segment(rec, segment_settings):
        sl = slice(seg.start, seg.stop)
        px, py, t = x[sl], y[sl], rec.t[sl]
        rest = max(round(settings.rest_s * rate), 1)
        ox, oy = float(px[:rest].mean()), float(py[:rest].mean())
        dist = np.hypot(px - ox, py - oy)
        peak = int(np.argmax(dist))
        moving = np.flatnonzero(dist > settings.onset_fraction * dist[peak])
        onset, end = (int(moving[0]), int(moving[-1])) if moving.size else (peak, peak)
        unit = _unit(seg.label)
        along = (px - ox) * unit[0] + (py - oy) * unit[1]
        across = np.abs((px - ox) * unit[1] - (py - oy) * unit[0])
        steps = np.hypot(np.diff(px[onset : end + 1]), np.diff(py[onset : end + 1]))
        length = float(steps.sum())
        duration = float(t[end] - t[onset])
        out.append(
            Movement(
                direction=seg.label,
                peak_reach=float(along.max()),
                path_length=length,
                deviation=float(across[onset : end + 1].mean()),
                time_to_peak_s=float(t[int(np.argmax(along))] - t[onset]),
                mean_speed=length / duration if duration > 0 else 0.0,
            )
        )
    return out


def _values(group: Sequence[Movement]) -> np.ndarray:
    """The descriptors of a direction's repetitions, (descriptors, repetitions) in `DESCRIPTORS` order."""
    return np.array([[m.value(d) for m in group] for d in DESCRIPTORS], dtype=np.float64)


def _means(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
    """Each sample's mean over repetitions, stacked: (samples, descriptors[, resamples])."""
    return np.stack(np.broadcast_arrays(*(np.mean(s, axis=axis) for s in samples)))


def _differences(*pairs: np.ndarray, axis: int = -1) -> np.ndarray:
    """Mean of b minus mean of a for the samples a₀, b₀, a₁, b₁, …, stacked: (pairs, descriptors[, …])."""
    means = _means(*pairs, axis=axis)
    return means[1::2] - means[0::2]


def _intervals(
    estimate: np.ndarray, interval: tuple[np.ndarray, np.ndarray] | None
) -> dict[str, dict[str, float | None]]:
    """Per descriptor ``{"mean", "low", "high"}`` of one direction; low/high None without an interval."""
    return {
        d: {
            "mean": float(estimate[i]),
            "low": None if interval is None else float(interval[0][i]),
            "high": None if interval is None else float(interval[1][i]),
        }
        for i, d in enumerate(DESCRIPTORS)
    }


def _row(
    estimates: np.ndarray, interval: tuple[np.ndarray, np.ndarray] | None, j: int, resampled: bool
) -> dict[str, dict[str, float | None]]:
    """`_intervals` of direction ``j`` of the (directions, descriptors) results; no interval unless it had
    repetitions to resample."""
    return _intervals(
        estimates[j], None if interval is None or not resampled else (interval[0][j], interval[1][j])
    )


def _by_direction(moves: Sequence[Movement]) -> dict[str, list[Movement]]:
    """Movements grouped by direction, directions in `DIRECTION_NAMES` order."""
    groups: dict[str, list[Movement]] = {}
    for name in DIRECTION_NAMES:
        found = [m for m in moves if m.direction == name]
        if found:
            groups[name] = found
    return groups


def summarise(moves: Sequence[Movement], settings: KinematicSettings = KinematicSettings()) -> dict[str, Any]:
    """The motion summary without the route's fields: ``{"directions": [{"direction", "n_segments",
    "peak_reach": {"mean", "low", "high"}, "path_length": …, "deviation": …, "time_to_peak_s": …,
    "mean_speed": …}, …]}`` in `DIRECTION_NAMES` order, only directions with movements."""
    groups = list(_by_direction(moves).items())
    values = [_values(group) for _, group in groups]
    rng = np.random.default_rng(settings.seed)
    interval = percentile_interval(values, _means, n_resamples=settings.n_boot, rng=rng) if values else None
    means = _means(*values) if values else np.empty((0, len(DESCRIPTORS)))
    rows = [
        {"direction": name, "n_segments": len(group)} | _row(means, interval, j, len(group) > 1)
        for j, (name, group) in enumerate(groups)
    ]
    return {"directions": rows}


def motion_summary(
    recordings: Sequence[Recording],
    *,
    segment_settings: SegmentSettings = SegmentSettings(),
    settings: KinematicSettings = KinematicSettings(),
) -> dict[str, Any]:
    """The kinematic summary of a demonstrator's recordings (movements pooled over recordings): `summarise`
    of `movements`. The route adds ``demonstrator_id`` and ``units``."""
    moves = [
        m for rec in recordings for m in movements(rec, segment_settings=segment_settings, settings=settings)
    ]
    return summarise(moves, settings)


def compare(
    a: Sequence[Movement], b: Sequence[Movement], settings: KinematicSettings = KinematicSettings()
) -> dict[str, Any]:
    """b minus a per direction and descriptor: ``{"directions": [{"direction", "n_a", "n_b",
    "peak_reach_diff": {"mean", "low", "high"}, …}], "a": summarise(a), "b": summarise(b)}`` over the
    directions both sides have; the interval resamples each side's repetitions independently."""
    groups_a, groups_b = _by_direction(a), _by_direction(b)
    both = [
        (name, groups_a[name], groups_b[name])
        for name in DIRECTION_NAMES
        if name in groups_a and name in groups_b
    ]
    pairs = [v for _, ga, gb in both for v in (_values(ga), _values(gb))]
    rng = np.random.default_rng(settings.seed)
    interval = (
        percentile_interval(pairs, _differences, n_resamples=settings.n_boot, rng=rng) if pairs else None
    )
    diffs = _differences(*pairs) if pairs else np.empty((0, len(DESCRIPTORS)))
    rows = []
    for j, (name, ga, gb) in enumerate(both):
        row = _row(diffs, interval, j, len(ga) > 1 or len(gb) > 1)
        rows.append(
            {"direction": name, "n_a": len(ga), "n_b": len(gb)} | {f"{d}_diff": v for d, v in row.items()}
        )
    return {"directions": rows, "a": summarise(a, settings), "b": summarise(b, settings)}


def compare_recordings(
    a: Sequence[Recording],
    b: Sequence[Recording],
    *,
    segment_settings: SegmentSettings = SegmentSettings(),
    settings: KinematicSettings = KinematicSettings(),
) -> dict[str, Any]:
    """`compare` of the movements in two demonstrators' (or sessions') recordings."""

    def moves(recs: Sequence[Recording]) -> list[Movement]:
        return [
            m for rec in recs for m in movements(rec, segment_settings=segment_settings, settings=settings)
        ]

    return compare(moves(a), moves(b), settings)


LABELS = {
    "peak_reach": "peak reach",
    "path_length": "path length",
    "deviation": "deviation from the line",
    "time_to_peak_s": "time to peak",
    "mean_speed": "mean speed",
}


def comparison_png(
    comparison: dict[str, Any],
    *,
    names: tuple[str, str] = ("a", "b"),
    units: str = "",
    time_unit: str = "s",
    dpi: int = 100,
) -> bytes:
    """`comparison_figure` as PNG bytes."""
    import io

    buffer = io.BytesIO()
    comparison_figure(comparison, names=names, units=units, time_unit=time_unit, dpi=dpi).savefig(
        buffer, format="png", bbox_inches="tight"
    )
    return buffer.getvalue()


def comparison_figure(
    comparison: dict[str, Any],
    *,
    names: tuple[str, str] = ("a", "b"),
    units: str = "",
    time_unit: str = "s",
    dpi: int = 100,
) -> Figure:
    """One figure of a `compare` result: peak reach per direction of both sides on a polar plot (bands: 95 %
    intervals), then one panel per descriptor with b − a per direction and its interval, red where the
    interval excludes 0; under it, each side's verdict on its learned readout (``learned.<side>.agreement``)
    where the comparison carries one. ``units``: the lengths' unit ("": none stated); ``time_unit``: the
    times'. matplotlib is imported here only, and drawn on an Agg canvas without pyplot (no global backend,
    safe in a server thread)."""
    import textwrap

    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.projections.polar import PolarAxes

    unit = f" ({units})" if units else ""
    fig = Figure(figsize=(15, 4.2), dpi=dpi)
    FigureCanvasAgg(fig)
    # An empty column after the polar plot: its direction labels would run into the first panel's.
    grid = fig.add_gridspec(1, 7, width_ratios=[1.6, 0.3, 1, 1, 1, 1, 1], wspace=0.45)
    polar = fig.add_subplot(grid[0, 0], projection="polar")
    assert isinstance(polar, PolarAxes)
    for side, name, colour in (("a", names[0], "tab:blue"), ("b", names[1], "tab:orange")):
        rows = comparison[side]["directions"]
        if not rows:
            continue
        angles = np.array([DIRECTION_NAMES.index(r["direction"]) * np.pi / 4 for r in rows])
        reach = np.array([r["peak_reach"]["mean"] for r in rows])
        low = np.array(
            [r["peak_reach"]["low"] if r["peak_reach"]["low"] is not None else np.nan for r in rows]
        )
        high = np.array(
            [r["peak_reach"]["high"] if r["peak_reach"]["high"] is not None else np.nan for r in rows]
        )
        closed = np.r_[angles, angles[:1]]
        polar.plot(closed, np.r_[reach, reach[:1]], "o-", color=colour, label=name)
        polar.fill_between(closed, np.r_[low, low[:1]], np.r_[high, high[:1]], color=colour, alpha=0.25)
    polar.set_xticks(np.arange(8) * np.pi / 4, [n.replace(" ", "\n") for n in DIRECTION_NAMES], fontsize=7)
    polar.set_rlabel_position(67.5)
    polar.tick_params(axis="y", labelsize=6)
    polar.set_title(f"peak reach{unit}", fontsize=10)
    polar.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8, ncol=1)
    rows = comparison["directions"]
    ypos = np.arange(len(rows))[::-1]
    for k, d in enumerate(DESCRIPTORS):
        ax = fig.add_subplot(grid[0, k + 2])
        for yk, row in zip(ypos, rows, strict=True):
            diff = row[f"{d}_diff"]
            clear = diff["low"] is not None and (diff["low"] > 0 or diff["high"] < 0)
            colour = "tab:red" if clear else "0.4"
            if diff["low"] is not None:
                ax.plot([diff["low"], diff["high"]], [yk, yk], color=colour, lw=2)
            ax.plot(diff["mean"], yk, "o", color=colour)
        ax.axvline(0.0, color="0.7", lw=1)
        # At least ±5 % of the descriptor's largest mean: differences that are rounding (float32 times) then
        # read as none, not as a panel of noise on a 1e-7 scale.
        floor = 0.05 * max(
            (
                abs(r[d]["mean"])
                for s in ("a", "b")
                for r in comparison[s]["directions"]
                if r[d]["mean"] is not None
            ),
            default=0.0,
        )
        left, right = ax.get_xlim()
        ax.set_xlim(min(left, -floor), max(right, floor))
        ax.set_yticks(ypos, [r["direction"] for r in rows] if k == 0 else [""] * len(rows), fontsize=8)
        what = (
            f" ({time_unit})"
            if d == "time_to_peak_s"
            else unit
            if d in LENGTHS
            else f" ({units} / {time_unit})"
            if units
            else ""
        )
        ax.set_title(f"{LABELS[d]}{what}", fontsize=9)
        ax.tick_params(axis="x", labelsize=7)
        ax.locator_params(axis="x", nbins=4)  # five ticks' labels of a narrow panel run together
    # Once for the five difference panels (in each panel's title, long session names ran into each other).
    fig.text(
        0.62,
        1.02,
        f"{names[1]} − {names[0]} per direction (95 % intervals; red: excludes 0)",
        ha="center",
        fontsize=10,
    )
    verdicts = [
        f"{name}, learned readout — {learned['agreement']['verdict']}: {learned['agreement']['detail']}"
        for side, name in (("a", names[0]), ("b", names[1]))
        if (learned := (comparison.get("learned") or {}).get(side)) and learned.get("agreement")
    ]
    if verdicts:  # the verdict beside the learned readout (docs/motion.md), never the readout alone
        fig.text(0.0, -0.06, "\n".join(textwrap.fill(v, 190) for v in verdicts), va="top", fontsize=8)
    return fig
