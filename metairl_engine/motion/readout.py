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

from collections.abc import Callable, Mapping, Sequence
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


def _offset(states: np.ndarray, k: int, *, width: int, height: int) -> float:
    """Mean signed offset, in cells and positive counter-clockwise, of the cells of ``states`` (velocity-grid
    state indices) from the instructed line of direction ``k`` (an index into `DIRECTIONS`) through the grid
    centre."""
    x, y, _ = velocity_coords(np.asarray(states, dtype=np.int64), width=width, height=height)
    ux, uy = DIRECTIONS[k] / np.hypot(*DIRECTIONS[k])
    return float(np.mean(-(x - (width - 1) / 2) * uy + (y - (height - 1) / 2) * ux))


def bend_levels(offsets: np.ndarray) -> np.ndarray:
    """The preference's level per direction from the paths' offsets (..., 8) in `DIRECTION_NAMES` order: the
    offsets taken as the preference's slopes around the centre, summed between neighbouring directions
    (trapezoid rule, 45° apart), the loop's closure error spread evenly, the levels centred. Linear, so a
    bootstrap can apply it to every resample at once. Returns (..., 8)."""
    slopes = np.asarray(offsets, dtype=np.float64)
    steps = (slopes + np.roll(slopes, -1, axis=-1)) / 2  # from direction k to k + 1 (45° counter-clockwise)
    n = slopes.shape[-1]
    levels = np.cumsum(steps, axis=-1) - steps - np.arange(n) / n * steps.sum(axis=-1, keepdims=True)
    return np.asarray(levels - levels.mean(axis=-1, keepdims=True))


def path_bend(visited: Mapping[str, np.ndarray], *, width: int, height: int) -> dict[str, float]:
    """Per direction, the level of the patient's preference at that direction's path relative to the others,
    read from which way the paths bend (``visited`` {direction: velocity-grid state indices}); empty unless
    all eight directions are there.

    A patient pulled toward what it prefers bends each out-and-back path toward the preferred side, so the
    mean signed offset of a path's cells from its instructed line (positive counter-clockwise) measures the
    preference's slope around the centre at that direction; `bend_levels` integrates the slopes around the
    circle. Model-free: it uses the paths only, no fit (docs/motion.md, "Path bend")."""
    if any(len(visited.get(d, ())) == 0 for d in DIRECTION_NAMES):
        return {}
    offsets = [_offset(visited[d], k, width=width, height=height) for k, d in enumerate(DIRECTION_NAMES)]
    return dict(zip(DIRECTION_NAMES, bend_levels(np.array(offsets)).tolist(), strict=True))


def path_offsets(
    paths: Mapping[str, Sequence[np.ndarray]], *, width: int, height: int
) -> dict[str, list[float]]:
    """Per direction, one value per repetition: the mean signed offset of the cells that repetition's path
    visits (``paths`` {direction: [velocity-grid state indices of one repetition, …]}) from the instructed
    line, the slope `path_bend` integrates. The verdict (`agreement`) resamples these repetitions."""
    return {
        d: [_offset(np.unique(s), k, width=width, height=height) for s in paths[d] if len(s)]
        for k, d in enumerate(DIRECTION_NAMES)
        if d in paths
    }


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
    """Whether a learned per-direction readout is consistent with the recordings: their peak reach and, where
    all eight directions were moved, which way their paths bend (`path_bend`).

    ``spearman``: ρ between the learned values and the mean peak reach across the directions both have
    (None with fewer than `MIN_DIRECTIONS`); ``p_positive`` / ``p_negative``: exact one-sided permutation
    p-values of that ρ; ``rho_low`` / ``rho_high``: its 95 % bootstrap interval over repetitions. The
    ``bend_`` fields are the same statistics of ρ between the learned values and the path-bend levels (None
    where the bend was not checked: fewer than `MIN_DIRECTIONS` directions, or not all eight directions
    moved)."""

    verdict: Verdict
    detail: str
    spearman: float | None = None
    p_positive: float | None = None
    p_negative: float | None = None
    rho_low: float | None = None
    rho_high: float | None = None
    n_directions: int = 0
    bend_spearman: float | None = None
    bend_p_positive: float | None = None
    bend_p_negative: float | None = None
    bend_rho_low: float | None = None
    bend_rho_high: float | None = None


@dataclass(frozen=True)
class RankingTest:
    """Spearman ρ of a learned ranking with one kind of recorded evidence, its exact one-sided permutation
    p-values, its 95 % bootstrap interval over repetitions, and each direction's evidence value with its
    interval (``value``, ``low``, ``high``: (n,), in the ranking's direction order)."""

    rho: float
    p_positive: float
    p_negative: float
    rho_low: float
    rho_high: float
    value: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @property
    def positive(self) -> bool:
        """ρ > 0 significantly: permutation p ≤ `ALPHA` and the bootstrap interval above 0."""
        return self.p_positive <= ALPHA and self.rho_low > 0

    @property
    def negative(self) -> bool:
        """ρ < 0 significantly: permutation p ≤ `ALPHA` and the bootstrap interval below 0."""
        return self.p_negative <= ALPHA and self.rho_high < 0


def _spearman_rows(ranked_learned: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Spearman ρ of one rank vector (n,) with each row of ``reach`` (m, n) (average ranks for ties)."""
    from scipy.stats import rankdata  # here only: the API process imports this module and never needs scipy

    ranks = rankdata(reach, axis=-1)
    a = ranked_learned - ranked_learned.mean()
    b = ranks - ranks.mean(axis=-1, keepdims=True)
    denominator = np.sqrt((a**2).sum() * (b**2).sum(axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(denominator > 0, (b @ a) / np.where(denominator > 0, denominator, 1.0), 0.0)


def ranking_test(
    ranked: np.ndarray,
    samples: Sequence[np.ndarray],
    evidence: Callable[[np.ndarray], np.ndarray],
    *,
    n_boot: int,
    seed: int,
) -> RankingTest:
    """Test the learned ranks ``ranked`` (n,) against evidence computed from repetitions: ``samples`` holds
    each source's repetitions, ``evidence`` maps the sources' means (..., m) to the n values ranked against
    (..., n). The permutation p-values are exact (every order of the n values, at most 8! = 40,320); the
    bootstrap resamples each source's repetitions (``n_boot`` draws, seeded) and recomputes the evidence."""
    value = evidence(np.array([s.mean() for s in samples]))
    rho = float(_spearman_rows(ranked, value[None, :])[0])
    orders = np.array(list(permutations(range(len(value)))))
    null = _spearman_rows(ranked, value[orders])  # ρ of the learned ranks with the evidence shuffled

    def rho_and_values(*resampled: np.ndarray, axis: int = -1) -> np.ndarray:
        """ρ with the evidence of the resampled means, then that evidence: (1 + n, resamples)."""
        means = np.stack(np.broadcast_arrays(*(r.mean(axis=axis) for r in resampled)), axis=-1)
        values = evidence(means)
        return np.concatenate([_spearman_rows(ranked, values)[None], np.moveaxis(values, -1, 0)])

    interval = percentile_interval(
        samples, rho_and_values, n_resamples=n_boot, rng=np.random.default_rng(seed), confidence=1 - ALPHA
    )
    if (
        interval is None
    ):  # no source has two repetitions: nothing bounds ρ, so no claim can rest on its interval
        n = len(value)
        interval = (np.r_[-1.0, np.full(n, -np.inf)], np.r_[1.0, np.full(n, np.inf)])
    low, high = interval
    return RankingTest(
        rho=rho,
        p_positive=float((null >= rho - 1e-12).mean()),
        p_negative=float((null <= rho + 1e-12).mean()),
        rho_low=float(low[0]),
        rho_high=float(high[0]),
        value=value,
        low=low[1:],
        high=high[1:],
    )


@dataclass(frozen=True)
class _Evidence:
    """One kind of recorded evidence a verdict tests the learned ranking against, with how a sentence names
    it (``name``) and its low and high ends (``lowest``, ``highest``: "reached least", …)."""

    test: RankingTest
    name: str
    lowest: str
    highest: str

    def summary(self) -> str:
        """ρ, its interval and its one-sided p-value in the direction of its sign, for a verdict's sentence."""
        t = self.test
        p_value = t.p_positive if t.rho >= 0 else t.p_negative
        return (
            f"Spearman ρ with the {self.name} {t.rho:+.2f}, bootstrap 95 % interval [{t.rho_low:+.2f}, "
            f"{t.rho_high:+.2f}], permutation p = {p_value:.3f}"
        )

    def contradiction(self, values: np.ndarray, names: Sequence[str]) -> str | None:
        """Why the learned ``values`` (in ``names`` order) run against this evidence, or None: ρ significantly
        below 0; or the direction favoured most is the one the evidence puts lowest, its 95 % interval below
        every other direction's (or the one favoured least is put highest, its interval above every other's)."""
        t = self.test
        top, bottom = int(np.argmax(values)), int(np.argmin(values))
        if t.negative:
            return f"it ranks the directions against the {self.name}"
        if t.high[top] < np.delete(t.low, top).min():
            return f"it favours {names[top]} most, the direction {self.lowest} (95 % interval below every other's)"
        if t.low[bottom] > np.delete(t.high, bottom).max():
            return f"it favours {names[bottom]} least, the direction {self.highest} (95 % interval above every other's)"
        return None

    def endorses(self, values: np.ndarray) -> bool:
        """Not against the learned ``values``: ρ ≥ 0 and the direction favoured most is not the one this
        evidence puts lowest."""
        return self.test.rho >= 0 and int(np.argmin(self.test.value)) != int(np.argmax(values))


def agreement(
    learned: Mapping[str, float | None],
    reach: Mapping[str, Sequence[float]],
    *,
    offsets: Mapping[str, Sequence[float]] | None = None,
    n_boot: int = 2000,
    seed: int = 0,
) -> Agreement:
    """The verdict on a learned readout ``learned`` {direction: ring-centred baseline} against the peak reach
    of every repetition ``reach`` {direction: [reach, …]} and, where ``offsets`` (`path_offsets`: {direction:
    [offset, …]}) covers all eight directions, against the path-bend levels (`bend_levels` of the mean
    offsets) (docs/motion.md, "Does the learned readout agree").

    ``disagrees``: the readout runs against the reach or the bend (`_Evidence.contradiction`: ρ significantly
    below 0, exact permutation p ≤ `ALPHA` and a bootstrap interval over repetitions below 0; or its favourite
    direction clearly lowest, or its least favoured clearly highest). ``agrees``: ρ with one of them
    significantly above 0, and neither against it (`_Evidence.endorses`: ρ ≥ 0 and its favourite direction not
    the lowest). Else ``undetermined``; with fewer than `MIN_DIRECTIONS` directions that have a learned value
    and movements, always. Without ``offsets`` for all eight directions the reach decides alone.
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
    from scipy.stats import rankdata  # here only, as in `_spearman_rows`

    ranked = rankdata(values)
    by_reach = ranking_test(
        ranked,
        [np.asarray(reach[d], dtype=np.float64) for d in names],
        lambda means: means,
        n_boot=n_boot,
        seed=seed,
    )
    by_bend = None
    if offsets is not None and all(len(offsets.get(d, ())) > 0 for d in DIRECTION_NAMES):
        chosen = [DIRECTION_NAMES.index(d) for d in names]
        by_bend = ranking_test(
            ranked,
            [np.asarray(offsets[d], dtype=np.float64) for d in DIRECTION_NAMES],
            lambda means: bend_levels(means)[..., chosen],
            n_boot=n_boot,
            seed=seed,
        )
    found = Agreement(
        "undetermined",
        "",
        by_reach.rho,
        by_reach.p_positive,
        by_reach.p_negative,
        by_reach.rho_low,
        by_reach.rho_high,
        n_directions=n,
    )
    if by_bend is not None:
        found = replace(
            found,
            bend_spearman=by_bend.rho,
            bend_p_positive=by_bend.p_positive,
            bend_p_negative=by_bend.p_negative,
            bend_rho_low=by_bend.rho_low,
            bend_rho_high=by_bend.rho_high,
        )
    evidence = [_Evidence(by_reach, "peak reach", "reached least", "reached most")]
    if by_bend is not None:
        evidence.append(
            _Evidence(by_bend, "path bend", "the paths bend least toward", "the paths bend most toward")
        )
    stats = f"over {n} directions: " + "; ".join(e.summary() for e in evidence)
    contradictions = [why for e in evidence if (why := e.contradiction(values, names))]
    if contradictions:
        return replace(
            found,
            verdict="disagrees",
            detail=f"The learned readout contradicts the recordings: {'; '.join(contradictions)} ({stats}). It "
            "is not the patient's preference; read reach and the weak side from the kinematic readout.",
        )
    if any(e.test.positive for e in evidence) and all(e.endorses(values) for e in evidence):
        return replace(
            found,
            verdict="agrees",
            detail=f"The learned readout ranks the directions as the recordings do ({stats}): its "
            "between-direction differences are consistent with them.",
        )
    return replace(
        found,
        detail="Do not read the learned ranking as the patient's preference: the recordings neither confirm "
        f"nor contradict it ({stats}), and on synthetic patients such unconfirmed rankings ran against the true "
        "preference about as often as with it. Read reach and the weak side from the kinematic readout.",
    )
