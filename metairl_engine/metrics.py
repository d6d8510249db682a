"""How good is a learned reward: correlations, EPIC-style distance, likelihood of held-out actions, EVD, key states.

numpy/scipy only (never torch): the API process computes comparisons with these functions.
A constant vector has no defined correlation; the correlations then return 0.0 (never NaN, so results
stay valid JSON).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import rankdata

from metairl_engine.mdp import MDP
from metairl_engine.planning import policy_evaluation, transition_matrix, value_iteration


def _masked(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Both vectors as float64, restricted to ``mask`` (boolean or index array) when given."""
    x, y = np.asarray(a, dtype=np.float64).ravel(), np.asarray(b, dtype=np.float64).ravel()
    if x.shape != y.shape:
        raise ValueError(f"vectors differ in length: {x.shape[0]} and {y.shape[0]}")
    if mask is not None:
        x, y = x[mask], y[mask]
    return x, y


def unit_scale(v: np.ndarray) -> np.ndarray:
    """``v`` divided by its largest magnitude (correlations are scale-invariant), so that sums, differences
    and squares of finite values near the float64 limits (±1e308) or near zero neither overflow nor
    underflow."""
    top = float(np.max(np.abs(v))) if v.size else 0.0
    return v / top if np.isfinite(top) and top > 0 else v


def _weighted_pearson(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """Pearson correlation of x and y under state weights w (normalised here); 0.0 when undefined."""
    x, y = unit_scale(x), unit_scale(y)
    if np.ptp(x) == 0 or np.ptp(y) == 0:
        return 0.0
    w = w / w.sum()
    dx, dy = x - w @ x, y - w @ y
    denom = np.sqrt((w @ (dx * dx)) * (w @ (dy * dy)))
    return float(np.clip((w @ (dx * dy)) / denom, -1.0, 1.0)) if denom > 1e-300 else 0.0


def pearson(a: np.ndarray, b: np.ndarray, *, mask: np.ndarray | None = None) -> float:
    """Pearson correlation of two reward vectors (optionally on the states selected by ``mask``)."""
    x, y = _masked(a, b, mask)
    return _weighted_pearson(x, y, np.ones_like(x)) if x.size > 1 else 0.0


def spearman(a: np.ndarray, b: np.ndarray, *, mask: np.ndarray | None = None) -> float:
    """Spearman rank correlation (Pearson of average ranks, ties shared)."""
    x, y = _masked(a, b, mask)
    return pearson(rankdata(x), rankdata(y)) if x.size > 1 else 0.0


def epic_distance(a: np.ndarray, b: np.ndarray, *, weights: np.ndarray | None = None) -> float:
    """EPIC-style pseudometric for state rewards: ``sqrt((1 − ρ_w) / 2)`` in [0, 1] (Gleave et al. 2021).

    For rewards of states alone, EPIC's canonicalisation removes the coverage-weighted mean, so the
    distance is that of the ``weights``-weighted Pearson correlation (uniform coverage by default).
    Scale- and shift-invariant: 0 for rewards inducing the same preferences, 1 for opposite ones.
    """
    x, y = _masked(a, b, None)
    w = np.ones_like(x) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if w.shape != x.shape or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be non-negative, one per state, not all zero")
    return float(np.sqrt((1.0 - _weighted_pearson(x, y, w)) / 2.0))


def key_states(task_reward: np.ndarray, baseline: np.ndarray, *, top: int) -> np.ndarray:
    """Indices of the ``top`` states where the task reward departs most from the baseline (paper §I); a state
    where the two are equal departs not at all and is none (a task reward that is the baseline has none)."""
    diff = np.abs(np.asarray(task_reward, dtype=np.float64) - np.asarray(baseline, dtype=np.float64))
    order = np.argsort(-diff, kind="stable")[: max(0, min(top, diff.size))]
    return order[diff[order] > 0].astype(np.int64)


def nll(policy: np.ndarray, states: np.ndarray, actions: np.ndarray) -> float:
    """Mean negative log-likelihood of demonstrated (state, action) pairs under ``policy`` (S, A)."""
    p = np.asarray(policy, dtype=np.float64)[np.asarray(states), np.asarray(actions)]
    return float(-np.mean(np.log(np.maximum(p, 1e-30))))


def accuracy(policy: np.ndarray, states: np.ndarray, actions: np.ndarray) -> float:
    """Fraction of demonstrated actions that are the policy's most likely action in their state."""
    return float(np.mean(np.argmax(np.asarray(policy)[np.asarray(states)], axis=1) == np.asarray(actions)))


def expected_value_difference(
    mdp: MDP, true_reward: np.ndarray, learned_reward: np.ndarray, *, start: np.ndarray | None = None
) -> float:
    """How much true value is lost by acting optimally for the learned reward (≥ 0; 0 is perfect).

    ``E_start[V*_true(s) − V^{π_learned}_true(s)]`` with π_learned greedy on the learned reward (one
    planning pass per reward, one policy evaluation); ``start`` is a start distribution (uniform default).
    `ValueError` unless each reward (and ``start``) has one value per state of ``mdp``.
    """
    for name, vector in (("true_reward", true_reward), ("learned_reward", learned_reward), ("start", start)):
        if vector is not None and np.shape(vector) != (mdp.n_states,):
            raise ValueError(f"{name} has shape {np.shape(vector)}; the MDP's states need ({mdp.n_states},)")
    p = transition_matrix(mdp)
    optimal = value_iteration(p, true_reward, gamma=mdp.gamma, backup="max")
    learned = value_iteration(p, learned_reward, gamma=mdp.gamma, backup="max")
    achieved = policy_evaluation(p, true_reward, learned.policy, gamma=mdp.gamma)
    w = np.full(mdp.n_states, 1.0 / mdp.n_states) if start is None else np.asarray(start) / np.sum(start)
    return float(w @ (optimal.value - achieved))
