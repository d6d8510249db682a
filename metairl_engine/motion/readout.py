"""What a velocity-grid baseline can say about a patient's inherent preference, and whether the recordings back it (numpy, scipy).

Out-and-back demonstrations of instruction k cover only the ray from the rest position along k. Along that
ray, "move outward, then back" (the task) and any preference that changes with the distance from the rest
position (the patient's) predict the same choices, so the *radial* profile of a learned baseline is not
identified by such data: it takes whatever the fit's prior gives it. What the data do constrain is how the
baseline differs between places at the same distance: between directions (the weak side against the
others) and across each ray (which way paths bend). `ring_centred` keeps only that part: it subtracts, from
every state's value, the mean over the given states at the same distance from the origin cell.
docs/motion.md (identifiability) and benchmarks/MOTION.md measure it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from itertools import permutations
from typing import Literal

import numpy as np

from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS, velocity_coords
from metairl_engine.motion.bootstrap import percentile_interval


def ring_centred(
    reward: np.ndarray,
    *,
    width: int,
    height: int,
    states: np.ndarray,
    origin: tuple[float, float] | None = None,
    ring: float = 1.0,
) -> np.ndarray:
    """``reward`` on ``states`` (velocity-grid state indices, (M,)) minus its mean over the states in the same
    ring: distance of the state's cell from ``origin`` (cell coordinates, default the grid centre) rounded
    to multiples of ``ring`` cells. Returns (M,) float64, in the order of ``states``."""
    x, y, _ = velocity_coords(np.asarray(states), width=width, height=height)
    ox, oy = ((width - 1) / 2, (height - 1) / 2) if origin is None else origin
    bins = np.round(np.hypot(x - ox, y - oy) / ring).astype(np.int64)
    values = np.asarray(reward, dtype=np.float64)[np.asarray(states)]
    sums = np.bincount(bins, weights=values)
    counts = np.bincount(bins)
    return np.asarray(values - (sums / np.maximum(counts, 1))[bins])


def direction_readout(
    reward: np.ndarray, visited: Mapping[str, np.ndarray], *, width: int, height: int
) -> dict[str, float]:
    """Per direction, the mean of the `ring_centred` ``reward`` over the states that direction's
    demonstrations visit (``visited`` {direction: state indices}); rings are centred over the union of
    all of them. Higher: the reward favours that direction's path (the service's ``baseline_ring_centred``)."""
    union = np.unique(np.concatenate([np.asarray(v, dtype=np.int64) for v in visited.values()]))
    centred = np.zeros(int(np.asarray(reward).shape[0]))
    centred[union] = ring_centred(reward, width=width, height=height, states=union)
    return {d: float(centred[np.asarray(v, dtype=np.int64)].mean()) for d, v in visited.items() if len(v)}


def path_bend(visited: Mapping[str, np.ndarray], *, width: int, height: int) -> dict[str, float]:
    """Per direction, the level of the patient's preference at that direction's path relative to the others,
    read from which way the paths bend (``visited`` {direction: velocity-grid state indices}); empty unless
    all eight directions are there.

    A patient pulled toward what it prefers bends each out-and-back path toward the preferred side, so the
    mean signed offset of a path's cells from its instructed line (positive counter-clockwise) measures the
    preference's slope around the centre at that direction. Summing the slopes of neighbouring directions
    (trapezoid rule, 45° apart) around the circle gives each direction's level up to a constant; the loop's
    closure error, spread evenly, is removed and the levels are centred. Model-free: it uses the paths only,
    no fit (docs/motion.md, "Path bend")."""
    if any(len(visited.get(d, ())) == 0 for d in DIRECTION_NAMES):
        return {}
    slopes = np.empty(len(DIRECTION_NAMES))
    for k, d in enumerate(DIRECTION_NAMES):
        x, y, _ = velocity_coords(np.asarray(visited[d], dtype=np.int64), width=width, height=height)
        ux, uy = DIRECTIONS[k] / np.hypot(*DIRECTIONS[k])
        slopes[k] = np.mean(-(x - (width - 1) / 2) * uy + (y - (height - 1) / 2) * ux)
    steps = (slopes + np.roll(slopes, -1)) / 2  # from direction k to k + 1 (45° counter-clockwise)
    levels = np.concatenate([[0.0], np.cumsum(steps)[:-1]]) - np.arange(len(steps)) / len(steps) * steps.sum()
    levels -= levels.mean()
    return {d: float(levels[k]) for k, d in enumerate(DIRECTION_NAMES)}


BASELINE_CAVEAT = (
    "Out-and-back movements identify how the baseline differs between directions and across each path, not "
    "how it changes with distance from the centre: moving out to the instructed distance is shared by every "
    "task and can be learned as part of the baseline. On synthetic patients whose paths are only bent by "
    "their preference (not planned), the baseline did not correlate with that preference. Read reach, "
    "the weak side and session differences from the kinematic readout; read the baseline as a preference "
    "only where its between-direction differences agree with it. The motion readout's `path_bend` ranks the "
    "directions from which way the paths bend, with no fit."
)
"""What the API should say next to a baseline learned from recordings (docs/api.md, "Motion readout"); see docs/motion.md."""


Verdict = Literal["agrees", "disagrees", "undetermined"]

MIN_DIRECTIONS = 4
"""The fewest directions a verdict ranks: below 4 no ranking is significant at 5 % (4! = 24 orders)."""

ALPHA = 0.05
"""One-sided level of the permutation test and of the bootstrap bound on Spearman's ρ."""


@dataclass(frozen=True)
class Agreement:
    """Whether a learned per-direction readout is consistent with the peak reach the recordings show.

    ``spearman``: ρ between the learned values and the mean peak reach across the directions both have
    (None with fewer than `MIN_DIRECTIONS`); ``p_positive`` / ``p_negative``: exact one-sided permutation
    p-values of that ρ; ``rho_low`` / ``rho_high``: its 95 % bootstrap interval over repetitions."""

    verdict: Verdict
    detail: str
    spearman: float | None = None
    p_positive: float | None = None
    p_negative: float | None = None
    rho_low: float | None = None
    rho_high: float | None = None
    n_directions: int = 0


def _spearman_rows(ranked_learned: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Spearman ρ of one rank vector (n,) with each row of ``reach`` (m, n) (average ranks for ties)."""
    from scipy.stats import rankdata  # here only: the API process imports this module and never needs scipy

    ranks = rankdata(reach, axis=-1)
    a = ranked_learned - ranked_learned.mean()
    b = ranks - ranks.mean(axis=-1, keepdims=True)
    denominator = np.sqrt((a**2).sum() * (b**2).sum(axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(denominator > 0, (b @ a) / np.where(denominator > 0, denominator, 1.0), 0.0)


def agreement(
    learned: Mapping[str, float | None],
    reach: Mapping[str, Sequence[float]],
    *,
    n_boot: int = 2000,
    seed: int = 0,
) -> Agreement:
    """The verdict on a learned readout ``learned`` {direction: ring-centred baseline} against the peak reach
    of every repetition ``reach`` {direction: [reach, …]} (docs/motion.md, "Does the learned readout agree").

    ``agrees``: ρ(learned, mean reach) > 0 with exact permutation p ≤ `ALPHA` and a bootstrap interval over
    repetitions above 0. ``disagrees``: the mirror image (ρ < 0, p ≤ `ALPHA`, interval below 0), or the
    direction the readout favours most is the one reached least, its 95 % interval below every other
    direction's (or the one it favours least is reached most, above every other's). Else ``undetermined``.
    """
    names = [d for d in DIRECTION_NAMES if learned.get(d) is not None and len(reach.get(d, ())) > 0]
    n = len(names)
    if n < MIN_DIRECTIONS:
        return Agreement(
            "undetermined",
            f"Only {n} direction(s) have both a learned value and recorded movements; at least "
            f"{MIN_DIRECTIONS} are needed to check the learned ranking against the recordings, so do not read "
            "the learned readout as the patient's preference.",
            n_directions=n,
        )
    values = np.array([float(learned[d]) for d in names])  # type: ignore[arg-type]
    reps = [np.asarray(reach[d], dtype=np.float64) for d in names]
    means = np.array([r.mean() for r in reps])
    from scipy.stats import rankdata  # here only, as in `_spearman_rows`

    ranked = rankdata(values)
    rho = float(_spearman_rows(ranked, means[None, :])[0])
    orders = np.array(list(permutations(range(n))))  # n ≤ 8: at most 40,320 orders, exact
    null = _spearman_rows(ranked, means[orders])  # ρ of the learned ranks with the reach shuffled
    p_pos = float((null >= rho - 1e-12).mean())
    p_neg = float((null <= rho + 1e-12).mean())

    def rho_and_means(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        """ρ of the learned ranks with the directions' mean reach, then those means: (1 + n, resamples)."""
        reach_means = np.stack(np.broadcast_arrays(*(r.mean(axis=axis) for r in samples)), axis=-1)
        return np.concatenate([_spearman_rows(ranked, reach_means)[None], np.moveaxis(reach_means, -1, 0)])

    interval = percentile_interval(
        reps, rho_and_means, n_resamples=n_boot, rng=np.random.default_rng(seed), confidence=1 - ALPHA
    )
    bounds = (np.r_[rho, means], np.r_[rho, means]) if interval is None else interval  # nothing to resample
    low, high = float(bounds[0][0]), float(bounds[1][0])
    lows, highs = bounds[0][1:], bounds[1][1:]
    found = Agreement("undetermined", "", rho, p_pos, p_neg, low, high, n_directions=n)
    stats = f"Spearman ρ = {rho:+.2f} over {n} directions, bootstrap 95 % interval [{low:+.2f}, {high:+.2f}]"
    top, bottom = int(np.argmax(values)), int(np.argmin(values))
    others_top, others_bottom = np.delete(np.arange(n), top), np.delete(np.arange(n), bottom)
    if p_pos <= ALPHA and low > 0:
        return replace(
            found,
            verdict="agrees",
            detail=f"The learned readout ranks the directions as their peak reach does ({stats}, permutation "
            f"p = {p_pos:.3f}): its between-direction differences are consistent with the recordings.",
        )
    if p_neg <= ALPHA and high < 0:
        why = f"it ranks the directions against their peak reach ({stats}, permutation p = {p_neg:.3f})"
    elif highs[top] < lows[others_top].min():
        why = (
            f"it favours {names[top]} most, the direction the patient reaches least (95 % interval of the "
            f"peak reach below every other direction's)"
        )
    elif lows[bottom] > highs[others_bottom].max():
        why = (
            f"it favours {names[bottom]} least, the direction the patient reaches most (95 % interval of the "
            f"peak reach above every other direction's)"
        )
    else:
        return replace(
            found,
            detail="Do not read the learned ranking as the patient's preference: the recordings neither "
            f"confirm nor contradict it ({stats}, one-sided permutation p = {min(p_pos, p_neg):.3f}), and on "
            "synthetic patients such unconfirmed rankings ran against the true preference about as often as "
            "with it. Read reach and the weak side from the kinematic readout.",
        )
    return replace(
        found,
        verdict="disagrees",
        detail=f"The learned readout contradicts the recordings: {why}. It is not the patient's preference; "
        "read reach and the weak side from the kinematic readout.",
    )
