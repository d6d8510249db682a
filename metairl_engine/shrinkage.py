"""Shrink each task reward towards the baseline, r_b + λ·S_q(r_i − r_b), chosen by held-out likelihood.

Why: with a few demonstrations per task, most of a task reward's deviation from the baseline is noise — the
task networks see every state's place and fit wiggles the demonstrations do not ask for — so the baseline,
learned from every task's demonstrations, is often closer to each task's truth than the task reward itself.
What a task adds to its demonstrator's shared reward is mostly local — a goal, an obstacle — so the candidates
also make the deviation sparse: S_q soft-thresholds it at the q-quantile of its magnitude (the proximal step
of an L1 penalty, a Laplace prior on the deviation), zeroing the smallest share q of the states' deviations
and keeping the large ones. Each candidate has its own optimal Q (value iteration, eq. 7 iterated), and the
ensemble's K members, each scored on the fold of steps it held out, give a cross-validated NLL per candidate.
The held-out steps of a few demonstrations cannot tell most candidates apart, so the choice follows the
one-standard-error rule the stopping step uses (Hastie et al., ESL §7.10): of the candidates within one
standard error of the best, the simplest, here the one whose rewards depart least from the baseline,
Σ|λ·S_q(r_i − r_b)| (the L1 norm S_q is the proximal step of): the most reward sharing the held-out steps
allow (`FitConfig.shrink_deviations`, docs/method.md "Shrinking towards the baseline").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import torch

from metairl_engine.backups import QRows, backup
from metairl_engine.config import Backup

SHRINKAGE = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The candidates λ: 0 gives every task the baseline, 1 the task network's own reward (what the fit learned)."""

SPARSITY = (0.0, 0.5, 0.9, 0.95, 0.99, 0.995)
"""The candidates q: the share of each network's states whose deviation from the baseline S_q sets to zero (0:
every deviation kept; with λ = 0 every deviation is gone, sparsity 1). The sparsest keep a task's deviation on
1 % and 0.5 % of the states: a goal and its neighbours on a 1,024-state grid, as local as a task can be."""

BUDGET = 2**17
"""The most task-states (T·K·S) on which the choice is made: value iteration of the 24 candidates would cost
more than a 16-task fit on an 80,000-state velocity grid (1,280,000 task-states: 5 CPU s per candidate
against 61 s for the fit), a tenth of a fit on the benchmark families' 1,024 states (32,768)."""

VALUE_TOLERANCE = 1e-4
"""Value iteration stops once no value moved by more than this fraction of the largest |reward|."""

SCORE_TOLERANCE = 1e-3
"""The same, for the candidates' Q that are only scored: their held-out NLLs differ by hundredths, far more than
a Q this close to its fixed point moves them; the chosen candidate's Q and V are then made to VALUE_TOLERANCE."""

MAX_ITERATIONS = 1000
"""Value iteration stops after this many sweeps at the latest (γ = 0.9 needs about 90 to VALUE_TOLERANCE)."""


@dataclass(frozen=True)
class Shrunk:
    """The chosen λ and q, and per network the shrunk rewards (T·K, S), their Q* (T·K, S, A) and V* (T·K, S)."""

    shrinkage: float
    sparsity: float
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
    tolerance: float = VALUE_TOLERANCE,
) -> tuple[torch.Tensor, torch.Tensor]:
    """(Q*, V*) of ``rewards`` (N, S) by value iteration from ``values`` until no value moves by more than
    ``tolerance`` of the largest |reward|; ``rows`` reads Q (N·S, A) off f = r + γV on every state of every
    network."""
    shape = (*rewards.shape, rows.n_actions)
    scale = float(rewards.abs().max().clamp_min(1e-12))
    for _ in range(MAX_ITERATIONS):
        new = backup(rows(rewards + gamma[:, None] * values).reshape(shape), kind=kind, bgi_k=bgi_k)
        moved = float((new - values).abs().max())
        values = new
        if moved <= tolerance * scale:
            break
    return rows(rewards + gamma[:, None] * values).reshape(shape), values


def sparse_deviation(deviation: torch.Tensor, sparsity: float) -> torch.Tensor:
    """S_q: each row of ``deviation`` (N, S) soft-thresholded at the ``sparsity`` quantile of its magnitude,
    sign(d)·max(|d| − τ, 0), so that share of the states' deviations becomes 0 (0: ``deviation`` itself)."""
    if sparsity == 0.0:
        return deviation
    tau = torch.quantile(deviation.abs(), sparsity, dim=1, keepdim=True)
    return deviation.sign() * (deviation.abs() - tau).clamp_min(0.0)


def shrink_deviations(
    rows: QRows,
    rewards: torch.Tensor,
    baseline: torch.Tensor,
    gamma: torch.Tensor,
    *,
    q: torch.Tensor,
    values: torch.Tensor,
    score: Callable[[torch.Tensor], torch.Tensor],
    kind: Backup,
    bgi_k: float,
) -> Shrunk:
    """Of the rewards r_b + λ·S_q(r − r_b) (λ in SHRINKAGE, q in SPARSITY) whose held-out NLL is within one
    standard error of the best, the one that departs least from the baseline; with its Q* and V*.

    ``rewards`` (N, S) are the networks' rewards, ``baseline`` (N, S) the baseline each is shrunk towards,
    ``q`` and ``values`` the networks' own Q and V (the optimal ones of ``rewards``: λ = 1, q = 0 costs
    nothing); ``score`` maps Q (N, S, A) to the NLL of each held-out step, lower is better.
    """
    deviation = rewards - baseline
    nll: dict[tuple[float, float], torch.Tensor] = {(1.0, 0.0): score(q)}
    departure: dict[tuple[float, float], float] = {}
    for sparsity in SPARSITY:
        kept = sparse_deviation(deviation, sparsity)
        size = float(kept.abs().sum())
        start = values  # each λ starts from the values of the one before it on this q: they are close
        for shrinkage in sorted(SHRINKAGE, reverse=True):
            departure.setdefault((shrinkage, sparsity if shrinkage else 0.0), shrinkage * size)
            if (shrinkage, sparsity) in nll or (shrinkage == 0.0 and sparsity > 0.0):
                continue  # λ = 0 is the baseline whatever q
            q_shrunk, start = optimal_q(
                rows,
                baseline + shrinkage * kept,
                gamma,
                values=start,
                kind=kind,
                bgi_k=bgi_k,
                tolerance=SCORE_TOLERANCE,
            )
            nll[shrinkage, sparsity] = score(q_shrunk)
    shrinkage, sparsity = one_standard_error_choice(nll, departure)
    if (shrinkage, sparsity) == (1.0, 0.0):
        return Shrunk(1.0, 0.0, rewards, q, values)
    shrunk = baseline + shrinkage * sparse_deviation(deviation, sparsity)
    q_shrunk, v_shrunk = optimal_q(rows, shrunk, gamma, values=values, kind=kind, bgi_k=bgi_k)
    return Shrunk(shrinkage, 1.0 if shrinkage == 0.0 else sparsity, shrunk, q_shrunk, v_shrunk)


def one_standard_error_choice(
    nll: Mapping[tuple[float, float], torch.Tensor], departure: Mapping[tuple[float, float], float]
) -> tuple[float, float]:
    """The (λ, q) to keep, given each candidate's NLL per held-out step and its rewards' departure from the
    baseline Σ|λ·S_q(r − r_b)|: of the candidates whose mean NLL is within one standard error (of the best's
    per-step NLLs) of the best, the one that departs least (λ = 0, the baseline alone, departs by nothing)."""
    best = min(nll.values(), key=lambda v: float(v.mean()))
    within = float(best.mean()) + (float(best.std()) / best.numel() ** 0.5 if best.numel() > 1 else 0.0)
    return min((choice for choice, v in nll.items() if float(v.mean()) <= within), key=departure.__getitem__)
