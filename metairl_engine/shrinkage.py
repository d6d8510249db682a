"""Shrink each task reward towards the baseline, r_b + λ·(r_i − r_b), with λ chosen by held-out likelihood.

Why: with a few demonstrations per task, most of a task reward's deviation from the baseline is noise — the
task networks see every state's place and fit wiggles the demonstrations do not ask for — so the baseline,
learned from every task's demonstrations, is often closer to each task's truth than the task reward itself.
How much of the deviation to keep is a question the data can answer: each shrunk reward has its own optimal
Q (value iteration, eq. 7 iterated), and the ensemble's K members, each scored on the fold of steps it held
out, give a cross-validated NLL per λ (`FitConfig.shrink_deviations`, docs/method.md "Shrinking towards the
baseline").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

from metairl_engine.backups import QRows, backup
from metairl_engine.config import Backup

SHRINKAGE = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The candidates λ: 0 gives every task the baseline, 1 the task network's own reward (what the fit learned)."""

BUDGET = 2**17
"""The most task-states (T·K·S) on which the choice is made: value iteration of the 4 candidates costs about
a fifth of a 16-task fit on an 80,000-state velocity grid (1,280,000 task-states: 5 CPU s per candidate
against 61 s for the fit), a few percent of a fit on the benchmark families' 1,024 states (32,768)."""

VALUE_TOLERANCE = 1e-4
"""Value iteration stops once no value moved by more than this fraction of the largest |reward|."""

MAX_ITERATIONS = 1000
"""Value iteration stops after this many sweeps at the latest (γ = 0.9 needs about 90 to VALUE_TOLERANCE)."""


@dataclass(frozen=True)
class Shrunk:
    """The chosen λ, and per network the shrunk rewards (T·K, S), their Q* (T·K, S, A) and V* (T·K, S)."""

    shrinkage: float
    rewards: torch.Tensor
    q: torch.Tensor
    values: torch.Tensor


def optimal_q(
    rows: QRows,
    rewards: torch.Tensor,
    gamma: torch.Tensor,
    *,
    values: torch.Tensor,
    kind: Backup,
    bgi_k: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(Q*, V*) of ``rewards`` (N, S) by value iteration from ``values``; ``rows`` reads Q (N·S, A) off
    f = r + γV on every state of every network."""
    shape = (*rewards.shape, rows.n_actions)
    scale = float(rewards.abs().max().clamp_min(1e-12))
    for _ in range(MAX_ITERATIONS):
        new = backup(rows(rewards + gamma[:, None] * values).reshape(shape), kind=kind, bgi_k=bgi_k)
        moved = float((new - values).abs().max())
        values = new
        if moved <= VALUE_TOLERANCE * scale:
            break
    return rows(rewards + gamma[:, None] * values).reshape(shape), values


def shrink_deviations(
    rows: QRows,
    rewards: torch.Tensor,
    baseline: torch.Tensor,
    gamma: torch.Tensor,
    *,
    q: torch.Tensor,
    values: torch.Tensor,
    score: Callable[[torch.Tensor], float],
    kind: Backup,
    bgi_k: float,
) -> Shrunk:
    """The λ in SHRINKAGE whose rewards r_b + λ·(r − r_b) score best, with their Q* and V*.

    ``rewards`` (N, S) are the networks' rewards, ``baseline`` (N, S) the baseline each is shrunk towards,
    ``q`` and ``values`` the networks' own Q and V (the optimal ones of ``rewards``: λ = 1 costs nothing);
    ``score`` maps Q (N, S, A) to the held-out NLL, lower is better (ties go to the larger λ).
    """
    best = Shrunk(1.0, rewards, q, values)
    best_score = score(q)
    for shrinkage in sorted(SHRINKAGE, reverse=True):
        if shrinkage == 1.0:
            continue
        shrunk = baseline + shrinkage * (rewards - baseline)
        q_shrunk, v_shrunk = optimal_q(rows, shrunk, gamma, values=values, kind=kind, bgi_k=bgi_k)
        candidate = score(q_shrunk)
        if candidate < best_score:
            best, best_score = Shrunk(shrinkage, shrunk, q_shrunk, v_shrunk), candidate
    return best
