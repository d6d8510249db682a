"""Reward distances that know the dynamics: EPIC and STARC under an MDP's transitions and discount.

numpy/scipy only (never torch): the API process computes comparisons with these functions.

Two rewards that differ by potential shaping, ``R'(s, a, s') = R(s, a, s') + γ Φ(s') − Φ(s)``, make every
policy equally good; a distance between rewards should not see that difference. Rewards here are of a
state, ``r(s)`` (shape ``(S,)``, what a fit learns), or of a state and action in the expected-next-state
form, ``R(s, a) = E[R(s, a, S') | S' ~ T(s, a)]`` (shape ``(S, A)``). A state reward is the (s, a) reward
``R(s, a) = r(s)``; shaping in that form is ``R + γ T Φ − Φ``, i.e. ``R(s, a) + γ Σ T(s'|s,a) Φ(s') − Φ(s)``.

**Canonicalisation** (`canonicalise`) removes the shaping exactly: of all rewards shaping-equivalent to R
it takes the one of least norm under the state–action weights D, ``C(R) = R − G Φ*`` with
``G Φ = γ T Φ − Φ`` and ``Φ* = argmin_Φ ‖R − G Φ‖_D`` (a sparse S×S least-squares solve). So
``C(R + G Φ) = C(R)`` for every Φ; constants are shaping too (Φ = −c / (1 − γ)), so C is shift-invariant.

- **EPIC** (Gleave et al. 2021) with dynamics: the Pearson distance ``sqrt((1 − ρ_D(C(Ra), C(Rb))) / 2)`` in
  [0, 1] of the canonical rewards under D — 0 for rewards equal up to shaping and positive scale.
- **STARC** (Skalse et al. 2024): ``‖C(Ra)/‖C(Ra)‖_D − C(Rb)/‖C(Rb)‖_D‖_D / 2`` in [0, 1], the same
  canonicalisation followed by normalisation (a reward that is all shaping normalises to 0).

D is a weighting of states (``uniform``, or the demonstrations' occupancy) times a uniform choice of
action. `bootstrap` gives percentile intervals by resampling the weighted states with replacement (the
canonical rewards held fixed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from metairl_engine.metrics import unit_scale

RIDGE = 1e-12
"""Relative ridge of the LU fallback's solve: pins Φ on states of weight 0, negligible elsewhere."""
FLAT_VARIANCE = 1e-10
"""`pairwise_epic`: a canonical reward whose D-variance is below this share of the reward's second moment is
taken as all shaping."""
CG_TOLERANCE = 1e-12
"""Relative residual at which the conjugate-gradient solve for Φ stops: `pairwise_epic` subtracts inner
products that nearly cancel for shaping-equivalent rewards, so at 1e-10 their distance came out 3e-6, not 0."""
CG_MAX_ITERATIONS = 20_000
"""Conjugate-gradient steps before the LU takes over (the 80,000-state velocity grid needs under 1,000 at γ 0.999)."""


@dataclass(frozen=True)
class Interval:
    """A bootstrap percentile interval."""

    low: float
    high: float


@dataclass(frozen=True)
class Distances:
    """EPIC and STARC distances of two rewards under one MDP and weighting, with optional intervals."""

    epic: float
    starc: float
    epic_interval: Interval | None
    starc_interval: Interval | None
    n_bootstrap: int


def shaping_operator(transitions: sp.spmatrix, gamma: float, n_actions: int) -> sp.csr_matrix:
    """G, the (S·A, S) matrix of ``Φ ↦ γ (T Φ)(s, a) − Φ(s)``; ``transitions`` is T as (S·A, S), row s·A + a."""
    n_states = transitions.shape[1]
    repeat = sp.kron(sp.identity(n_states, format="csr"), np.ones((n_actions, 1)), format="csr")
    return (gamma * sp.csr_matrix(transitions) - repeat).tocsr()


def as_state_action(reward: np.ndarray, n_states: int, n_actions: int) -> np.ndarray:
    """A state reward (S,) or an (S, A) reward as the flat (S·A,) vector of R(s, a)."""
    r = np.asarray(reward, dtype=np.float64)
    if r.shape == (n_states,):
        return np.repeat(r, n_actions)
    if r.shape == (n_states, n_actions) or r.shape == (n_states * n_actions,):
        return r.reshape(-1)
    raise ValueError(f"a reward must have shape ({n_states},) or ({n_states}, {n_actions}), got {r.shape}")


def state_action_weights(state_weights: np.ndarray | None, n_states: int, n_actions: int) -> np.ndarray:
    """D over (s, a), flat: the state weights (uniform if None) normalised, times 1/A per action."""
    w = np.ones(n_states) if state_weights is None else np.asarray(state_weights, dtype=np.float64).ravel()
    if w.shape != (n_states,) or np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
        raise ValueError("state weights must be finite, non-negative, one per state and not all zero")
    return np.repeat(w / w.sum(), n_actions) / n_actions


def lockstep_cg(
    matrix: sp.csr_matrix, targets: np.ndarray, inverse_diagonal: np.ndarray
) -> tuple[np.ndarray, bool]:
    """X solving ``matrix @ X = targets`` ((S, k): k right-hand sides) by k Jacobi-preconditioned conjugate-
    gradient solves run in lockstep, one sparse product with all k columns a step; and whether every column's
    residual fell below `CG_TOLERANCE` of its target's norm. scipy's ``cg`` takes one right-hand side and
    spends most of its time in its own per-step bookkeeping: 3.0 s of CPU a reward on the 80,000-state
    velocity grid, where this took 0.6 s a reward, for one reward or nine."""
    x = np.zeros_like(targets)
    residual = targets.copy()
    z = inverse_diagonal[:, None] * residual
    direction = z.copy()
    rz = np.einsum("ij,ij->j", residual, z)
    stop = CG_TOLERANCE * np.linalg.norm(targets, axis=0)
    for _ in range(CG_MAX_ITERATIONS):
        active = np.linalg.norm(residual, axis=0) > stop
        if not active.any():
            return x, True
        product = matrix @ direction
        curvature = np.einsum("ij,ij->j", direction, product)
        alpha = np.where(active, rz / np.where(active, curvature, 1.0), 0.0)  # αₖ = rᵀz / pᵀAp
        x += alpha * direction
        residual -= alpha * product
        z = inverse_diagonal[:, None] * residual
        rz_next = np.einsum("ij,ij->j", residual, z)
        beta = np.where(active, rz_next / np.where(active, rz, 1.0), 0.0)  # βₖ = rₖ₊₁ᵀzₖ₊₁ / rₖᵀzₖ
        direction = z + beta * direction
        rz = rz_next
    return x, False


def potentials(targets: np.ndarray, shaping: sp.csr_matrix, weights: np.ndarray) -> np.ndarray:
    """Φ* ((S, k)) solving the normal equations Gᵀ D G Φ = ``targets`` (Gᵀ D R, one column per reward) by
    conjugate gradients (`lockstep_cg`): memory of the order of G's entries, where a sparse LU's fill-in took
    1.2 GB on the 80,000-state velocity grid (0.7 s of CPU for a reward there at γ 0.9 and 1.8 s at γ 0.999,
    against 9 s for the LU; canonical rewards within 3e-12 of its, relative to their peak). States of weight 0 leave Φ free there; the solve,
    started at 0, leaves it 0. Should it not converge, the LU solves instead (a tiny ridge pinning Φ where
    it is free)."""
    normal = (shaping.T @ (sp.diags(weights) @ shaping)).tocsr()
    diagonal = normal.diagonal()
    floor = float(diagonal.max(initial=0.0)) * 1e-12 or 1.0  # a state no weighted step reaches: its row is 0
    phi, converged = lockstep_cg(normal, targets, 1.0 / np.maximum(diagonal, floor))
    if not converged:
        ridged = normal + RIDGE * (float(diagonal.mean()) or 1.0) * sp.identity(normal.shape[0])
        phi = splu(ridged.tocsc()).solve(targets)
    return np.asarray(phi)


def canonicalise(reward: np.ndarray, shaping: sp.csr_matrix, weights: np.ndarray) -> np.ndarray:
    """C(R) = R − G Φ*, Φ* minimising ‖R − G Φ‖ under ``weights`` (`potentials`): the least-norm reward
    shaping-equivalent to R. ``reward`` is one flat (S·A,) reward or k of them as (k, S·A)."""
    r = np.asarray(reward, dtype=np.float64)
    rows = r.reshape(-1, r.shape[-1])
    phi = potentials(np.asarray(shaping.T @ (weights * rows).T), shaping, weights)
    return np.asarray(rows - (shaping @ phi).T).reshape(r.shape)


def _pearson(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    """Weighted Pearson correlation; 0.0 when a side is constant where w > 0."""
    w = w / w.sum()
    dx, dy = x - w @ x, y - w @ y
    vx, vy = w @ (dx * dx), w @ (dy * dy)
    scale = max(float(np.max(np.abs(x))), float(np.max(np.abs(y))), 1e-300)
    if vx <= (1e-12 * scale) ** 2 or vy <= (1e-12 * scale) ** 2:
        return 0.0
    return float(np.clip((w @ (dx * dy)) / np.sqrt(vx * vy), -1.0, 1.0))


def _epic(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    return float(np.sqrt(max(0.0, 1.0 - _pearson(x, y, w)) / 2.0))


def _starc(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> float:
    w = w / w.sum()

    def unit(v: np.ndarray) -> np.ndarray:
        norm = float(np.sqrt(w @ (v * v)))
        scale = max(float(np.max(np.abs(v))), 1e-300)
        return v / norm if norm > 1e-9 * scale else np.zeros_like(v)

    d = unit(x) - unit(y)
    return float(min(1.0, np.sqrt(w @ (d * d)) / 2.0))


def distances(
    a: np.ndarray,
    b: np.ndarray,
    *,
    transitions: sp.spmatrix,
    gamma: float,
    n_actions: int,
    state_weights: np.ndarray | None = None,
    bootstrap: int = 0,
    seed: int = 0,
) -> Distances:
    """EPIC and STARC distances of rewards ``a`` and ``b`` ((S,) or (S, A)) under the MDP's transitions
    (T as (S·A, S)) and ``gamma``, states weighted by ``state_weights`` (uniform if None); with
    ``bootstrap`` > 0, 95 % percentile intervals from that many resamplings of the weighted states."""
    if not 0.0 <= gamma < 1.0:
        raise ValueError(f"gamma must be in [0, 1), got {gamma}")
    n_states = transitions.shape[1]
    w = state_action_weights(state_weights, n_states, n_actions)
    shaping = shaping_operator(transitions, gamma, n_actions)
    # Both distances ignore positive scale: scaling to unit peak first keeps rewards near ±1e308 finite.
    ca, cb = canonicalise(
        np.stack([unit_scale(as_state_action(r, n_states, n_actions)) for r in (a, b)]), shaping, w
    )
    epic, starc = _epic(ca, cb, w), _starc(ca, cb, w)
    if bootstrap <= 0:
        return Distances(epic, starc, None, None, 0)
    rng = np.random.default_rng(seed)
    support = np.flatnonzero(w.reshape(n_states, n_actions).sum(axis=1) > 0)
    samples = np.empty((bootstrap, 2))
    for i in range(bootstrap):
        counts = np.bincount(rng.choice(support, size=support.size), minlength=n_states)
        wb = w * np.repeat(counts, n_actions)
        samples[i] = _epic(ca, cb, wb), _starc(ca, cb, wb)
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)
    return Distances(
        epic,
        starc,
        Interval(float(low[0]), float(high[0])),
        Interval(float(low[1]), float(high[1])),
        bootstrap,
    )


def shaped(
    reward: np.ndarray, potential: np.ndarray, *, transitions: sp.spmatrix, gamma: float, n_actions: int
) -> np.ndarray:
    """``reward`` shaped by ``potential`` in the expected-next-state form: (S, A) values of
    ``R(s, a) + γ Σ_s' T(s'|s, a) Φ(s') − Φ(s)``."""
    n_states = transitions.shape[1]
    r = as_state_action(reward, n_states, n_actions)
    out = r + shaping_operator(transitions, gamma, n_actions) @ np.asarray(potential, dtype=np.float64)
    return np.asarray(out).reshape(n_states, n_actions)


def pairwise_epic(
    rewards: list[np.ndarray],
    *,
    transitions: sp.spmatrix,
    gamma: float,
    n_actions: int,
    state_weights: np.ndarray | None = None,
) -> np.ndarray:
    """The symmetric matrix of EPIC distances (with dynamics) between every pair of ``rewards`` ((S,) or
    (S, A) each), from the D-inner products of their canonical forms without forming them.

    With bᵢ = Gᵀ D Rᵢ and Φᵢ its `potentials`, the normal equations make C(Rᵢ) D-orthogonal to every G Φ, so
    ⟨C(Rᵢ), C(Rⱼ)⟩_D = ⟨Rᵢ, Rⱼ⟩_D − bᵢᵀ Φⱼ and the D-mean of C(Rᵢ) is ⟨Rᵢ, 1⟩_D − Φᵢᵀ Gᵀ D 1 (D sums to 1):
    memory of a few vectors of S values per reward beside the solve's, where k canonical rewards of S·A
    values each took 300 MB for 17 rewards on the 80,000-state velocity grid."""
    n_states = transitions.shape[1]
    w = state_action_weights(state_weights, n_states, n_actions)
    shaping = shaping_operator(transitions, gamma, n_actions)
    # Scale-free, so each at unit peak: products of rewards near ±1e308 stay finite.
    scaled = [unit_scale(np.asarray(r, dtype=np.float64)) for r in rewards]
    targets = np.column_stack([shaping.T @ (w * as_state_action(r, n_states, n_actions)) for r in scaled])
    phi = potentials(targets, shaping, w)
    if all(r.shape == (n_states,) for r in scaled):  # state rewards: D summed over actions
        per_state = w.reshape(n_states, n_actions).sum(axis=1)
        x = np.stack(scaled)
        inner, level = (x * per_state) @ x.T, x @ per_state
    else:
        x = np.stack([as_state_action(r, n_states, n_actions) for r in scaled])
        inner, level = (x * w) @ x.T, x @ w
    gram = inner - targets.T @ phi
    mean = level - phi.T @ (shaping.T @ w)
    covariance = (gram + gram.T) / 2 - np.outer(mean, mean)
    variance = np.diag(covariance).copy()
    # A reward all shaping correlates with nothing, as `_pearson` has it; "all" up to what float32 transition
    # probabilities leave of a constant's canonical form (~1e-7 of it, so ~1e-14 of its second moment).
    flat = variance <= FLAT_VARIANCE * np.maximum(np.diag(inner), 1e-300)
    spread = np.sqrt(np.where(flat, 1.0, variance))
    rho = np.clip(covariance / np.outer(spread, spread), -1.0, 1.0)
    rho[flat, :] = 0.0
    rho[:, flat] = 0.0
    out = np.sqrt(np.maximum(0.0, 1.0 - rho) / 2.0)
    np.fill_diagonal(out, 0.0)
    return np.asarray(out)
