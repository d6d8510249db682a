"""Readings of a motion fit that might rank a patient's per-direction preference (an exploration, not a served readout).

Each reading maps one session's fit (`SessionFit`: the learned rewards, values and policies and the
demonstrations they were fitted on) to one value per instructed direction, higher meaning more preferred.
``python -m benchmarks.motion readings`` scores every reading against the patient's true per-direction
preference (docs/motion.md, "Why no reading of the fit ranks a controller's preference"). Only
`served` is a product readout (the service's ``baseline_ring_centred``); the others are variations on it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.stats import spearmanr

from metairl_engine import Trajectory
from metairl_engine.fit import FitResult
from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS, velocity_coords, velocity_state
from metairl_engine.mdp import MDP
from metairl_engine.motion.readout import (
    bend_levels,
    direction_readout,
    path_bend,
    path_offsets,
    ring_centred,
)
from metairl_engine.planning import transition_matrix, value_iteration


@dataclass(frozen=True)
class SessionFit:
    """One session's fit over all its directions (``result``'s tasks in ``directions`` order), the
    demonstrations it was fitted on (``paths`` {direction: [trajectory, …]}), its MDP and its wall time."""

    result: FitResult
    paths: dict[str, list[Trajectory]]
    mdp: MDP
    width: int
    height: int
    wall_s: float

    @property
    def directions(self) -> list[str]:
        """The directions that have demonstrations, in `DIRECTION_NAMES` order (the fit's task order)."""
        return list(self.paths)

    @cached_property
    def visited(self) -> dict[str, np.ndarray]:
        """Per direction, the velocity-grid states its demonstrations visit (sorted, unique)."""
        return {d: np.unique(np.concatenate([t.states for t in ts])) for d, ts in self.paths.items()}

    @cached_property
    def union(self) -> np.ndarray:
        """The states any demonstration visits (sorted, unique)."""
        return np.unique(np.concatenate(list(self.visited.values())))


Reading = Callable[[SessionFit], dict[str, float]]
"""A reading: one value per direction from a session's fit (higher: more preferred)."""


# --- shared pieces ------------------------------------------------------------------------------------------


def _centred(
    values: np.ndarray, fit: SessionFit, *, ring: float = 1.0, by_channel: bool = False
) -> np.ndarray:
    """``values`` (S,) `ring_centred` over all visited states (rings ``ring`` cells wide; with ``by_channel``,
    each velocity channel's states centred on their own); 0 on unvisited states."""
    out = np.zeros(len(values))
    groups = [fit.union]
    if by_channel:
        channel = velocity_coords(fit.union, width=fit.width, height=fit.height)[2]
        groups = [fit.union[channel == c] for c in np.unique(channel)]
    for states in groups:
        out[states] = ring_centred(values, width=fit.width, height=fit.height, states=states, ring=ring)
    return out


def _path_means(values: np.ndarray, fit: SessionFit) -> dict[str, float]:
    """Per direction, the mean of ``values`` (S,) over the states its demonstrations visit."""
    return {d: float(values[s].mean()) for d, s in fit.visited.items()}


def _served(values: np.ndarray, fit: SessionFit) -> dict[str, float]:
    """The served per-direction readout (`direction_readout`) of any reward-like ``values`` (S,)."""
    return direction_readout(values, fit.visited, width=fit.width, height=fit.height)


def _own_task(values: np.ndarray, fit: SessionFit) -> dict[str, float]:
    """Per direction, the served readout of that direction's own row of ``values`` (T, S), on its own path."""
    return {d: _served(values[i], fit)[d] for i, d in enumerate(fit.directions)}


def _distance(states: np.ndarray, fit: SessionFit) -> np.ndarray:
    """Distance in cells of each state's cell from the grid centre."""
    x, y, _ = velocity_coords(states, width=fit.width, height=fit.height)
    return np.asarray(np.hypot(x - (fit.width - 1) / 2, y - (fit.height - 1) / 2))


def _across(k: int) -> np.ndarray:
    """The unit vector (2,) counter-clockwise across the instructed line of direction index ``k``."""
    ux, uy = DIRECTIONS[k] / np.hypot(*DIRECTIONS[k])
    return np.array([-uy, ux])


def _around(slopes: Mapping[str, float]) -> dict[str, float]:
    """Per-direction slopes around the centre summed into levels as `path_bend` sums the paths' offsets (empty
    unless all eight directions are there)."""
    if any(d not in slopes for d in DIRECTION_NAMES):
        return {}
    return dict(
        zip(DIRECTION_NAMES, bend_levels(np.array([slopes[d] for d in DIRECTION_NAMES])), strict=True)
    )


def _peaks(fit: SessionFit, direction: str) -> np.ndarray:
    """Each of a direction's demonstrations' state farthest from the centre (one per repetition)."""
    return np.array([t.states[int(np.argmax(_distance(t.states, fit)))] for t in fit.paths[direction]])


def _steps(fit: SessionFit, direction: str) -> tuple[np.ndarray, np.ndarray]:
    """The (state, action) pairs of a direction's demonstrations, concatenated."""
    ts = fit.paths[direction]
    return (
        np.concatenate([t.states[: len(t.actions)] for t in ts]),
        np.concatenate([t.actions for t in ts]),
    )


def policy_drift(fit: SessionFit) -> dict[str, float]:
    """Per direction, its learned policy's expected move across the instructed line (cells per step,
    counter-clockwise positive), averaged over the states of its demonstrations' steps."""
    out = {}
    for i, d in enumerate(fit.directions):
        states, _ = _steps(fit, d)
        out[d] = float(
            (fit.result.policies[i][states] @ (DIRECTIONS @ _across(DIRECTION_NAMES.index(d)))).mean()
        )
    return out


def demonstrated_drift(fit: SessionFit) -> dict[str, float]:
    """Per direction, its demonstrations' mean move across the instructed line (as `policy_drift`)."""
    out = {}
    for d in fit.directions:
        _, actions = _steps(fit, d)
        out[d] = float((DIRECTIONS[actions] @ _across(DIRECTION_NAMES.index(d))).mean())
    return out


def offsets(fit: SessionFit) -> dict[str, float]:
    """Per direction, the mean signed offset of its visited cells from the instructed line (`path_bend`'s slope)."""
    found = path_offsets({d: [s] for d, s in fit.visited.items()}, width=fit.width, height=fit.height)
    return {d: v[0] for d, v in found.items()}


# --- the readings -------------------------------------------------------------------------------------------


def served(fit: SessionFit) -> dict[str, float]:
    """The served readout: the baseline ring-centred (1-cell rings) over all visited states, mean on each path."""
    return _served(fit.result.baseline, fit)


def rings_2(fit: SessionFit) -> dict[str, float]:
    """As served, rings 2 cells wide."""
    return _path_means(_centred(fit.result.baseline, fit, ring=2.0), fit)


def rings_3(fit: SessionFit) -> dict[str, float]:
    """As served, rings 3 cells wide."""
    return _path_means(_centred(fit.result.baseline, fit, ring=3.0), fit)


def rings_by_channel(fit: SessionFit) -> dict[str, float]:
    """As served, each velocity channel's visited states ring-centred on their own."""
    return _path_means(_centred(fit.result.baseline, fit, by_channel=True), fit)


def channel_offsets_removed(fit: SessionFit) -> dict[str, float]:
    """As served, after subtracting from the baseline its mean over each velocity channel (all states)."""
    channels = fit.result.baseline.reshape(8, -1).astype(np.float64)
    return _served((channels - channels.mean(axis=1, keepdims=True)).reshape(-1), fit)


def cell_average(fit: SessionFit) -> dict[str, float]:
    """As served, on the baseline averaged over the 8 velocity channels per cell."""
    return _served(np.tile(fit.result.baseline.reshape(8, -1).mean(axis=0), 8), fit)


def outer_half(fit: SessionFit) -> dict[str, float]:
    """As served, averaged only over a path's states at least half as far out as its farthest visited cell."""
    centred = _centred(fit.result.baseline, fit)
    out = {}
    for d, states in fit.visited.items():
        far = _distance(states, fit)
        out[d] = float(centred[states[far >= far.max() / 2]].mean())
    return out


def visit_weighted(fit: SessionFit) -> dict[str, float]:
    """As served, each path's mean weighted by how often its demonstrations visit each state."""
    centred = _centred(fit.result.baseline, fit)
    return {d: float(centred[np.concatenate([t.states for t in ts])].mean()) for d, ts in fit.paths.items()}


def less_log_visits(fit: SessionFit) -> dict[str, float]:
    """As served, on the baseline's residual (visited states) after a least-squares line on log visit count."""
    every = np.concatenate([t.states for ts in fit.paths.values() for t in ts])
    counts = np.bincount(every, minlength=len(fit.result.baseline))[fit.union]
    design = np.column_stack([np.ones(len(counts)), np.log(counts)])
    target = fit.result.baseline[fit.union].astype(np.float64)
    residual = np.zeros(len(fit.result.baseline))
    residual[fit.union] = target - design @ np.linalg.lstsq(design, target, rcond=None)[0]
    return _served(residual, fit)


def task_mean(fit: SessionFit) -> dict[str, float]:
    """As served, on the mean of the task rewards instead of the baseline."""
    return _served(fit.result.rewards.mean(axis=0), fit)


def own_task_reward(fit: SessionFit) -> dict[str, float]:
    """Each direction's own task reward, ring-centred as served, on its own path."""
    return _own_task(fit.result.rewards, fit)


def baseline_soft_value(fit: SessionFit) -> dict[str, float]:
    """As served, on the baseline's soft value (soft value iteration, the fit's gamma and confidence)."""
    plan = value_iteration(
        transition_matrix(fit.mdp),
        fit.result.baseline,
        gamma=fit.mdp.gamma,
        confidence=fit.result.config.confidence,
    )
    return _served(plan.value, fit)


def own_task_value(fit: SessionFit) -> dict[str, float]:
    """Each direction's own task value (the fit's ``values``), ring-centred as served, on its own path."""
    return _own_task(fit.result.values, fit)


def peak_reward(fit: SessionFit) -> dict[str, float]:
    """Each direction's own task reward at its demonstrations' farthest states, mean over repetitions."""
    return {d: float(fit.result.rewards[i][_peaks(fit, d)].mean()) for i, d in enumerate(fit.directions)}


def peak_reward_relative(fit: SessionFit) -> dict[str, float]:
    """Each direction's own task reward at its path's peaks (as above) less the other tasks' mean reward there."""
    out = {}
    for i, d in enumerate(fit.directions):
        at_peaks = fit.result.rewards[:, _peaks(fit, d)].mean(axis=1)
        out[d] = float(at_peaks[i] - np.delete(at_peaks, i).mean())
    return out


def baseline_slope(fit: SessionFit) -> dict[str, float]:
    """The baseline's mean slope across each path (counter-clockwise positive), summed as path_bend sums offsets."""
    slopes = {}
    for d, states in fit.visited.items():
        k = DIRECTION_NAMES.index(d)
        step = np.array([-DIRECTIONS[k][1], DIRECTIONS[k][0]])  # central difference across, same channel
        x, y, c = velocity_coords(states, width=fit.width, height=fit.height)
        xp, yp = np.clip(x + step[0], 0, fit.width - 1), np.clip(y + step[1], 0, fit.height - 1)
        xm, ym = np.clip(x - step[0], 0, fit.width - 1), np.clip(y - step[1], 0, fit.height - 1)
        span = ((xp - xm) * step[0] + (yp - ym) * step[1]) / np.hypot(*step)  # cells, along the unit across
        ok = span > 0
        rise = (
            fit.result.baseline[velocity_state(xp, yp, c, width=fit.width, height=fit.height)]
            - fit.result.baseline[velocity_state(xm, ym, c, width=fit.width, height=fit.height)]
        )
        slopes[d] = float((rise[ok] / span[ok]).mean())
    return _around(slopes)


def policy_drift_around(fit: SessionFit) -> dict[str, float]:
    """The learned policies' sideways drift (`policy_drift`) summed around the centre as path_bend sums offsets."""
    return _around(policy_drift(fit))


def bend(fit: SessionFit) -> dict[str, float]:
    """The model-free `path_bend` readout of the same demonstrations (no fit), for comparison."""
    return path_bend(fit.visited, width=fit.width, height=fit.height)


READINGS: dict[str, Reading] = {
    "served readout (`baseline_ring_centred`)": served,
    "rings 2 cells wide": rings_2,
    "rings 3 cells wide": rings_3,
    "rings split by velocity channel": rings_by_channel,
    "each channel's offset removed first": channel_offsets_removed,
    "baseline averaged over channels per cell": cell_average,
    "outer half of each path": outer_half,
    "weighted by visits": visit_weighted,
    "less its regression on the log visit count": less_log_visits,
    "task rewards' mean": task_mean,
    "each task's own reward on its path": own_task_reward,
    "baseline's soft value": baseline_soft_value,
    "each task's value on its path": own_task_value,
    "each task's reward at its path's peak": peak_reward,
    "… relative to the other tasks' rewards there": peak_reward_relative,
    "baseline's slope across each path, summed around the centre": baseline_slope,
    "learned policies' sideways drift, summed around the centre": policy_drift_around,
}
"""The readings of a fit, in docs/motion.md's order: the table's names and their functions."""

COMPARISON: dict[str, Reading] = {"path bend (`path_bend`, no fit)": bend}
"""Scored beside the readings: the model-free readout the docs recommend instead."""


def spearman(values: Mapping[str, float], truth: Mapping[str, float]) -> float:
    """Spearman ρ of ``values`` with ``truth`` over the directions both have (nan with fewer than 2)."""
    names = [d for d in DIRECTION_NAMES if d in values and d in truth]
    if len(names) < 2:
        return float("nan")
    return float(spearmanr([values[d] for d in names], [truth[d] for d in names])[0])


def score(fit: SessionFit, truth_reward: np.ndarray, readings: Mapping[str, Reading]) -> dict[str, float]:
    """Each reading's Spearman with the true per-direction preference (the served readout of ``truth_reward``,
    as the agreement benchmark's truth)."""
    truth = _served(truth_reward, fit)
    return {name: spearman(reading(fit), truth) for name, reading in readings.items()}
