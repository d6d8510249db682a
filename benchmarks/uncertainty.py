"""Does the reward's spread across the ensemble's members say where the learned reward is wrong?

One default fit per world of every family: the terrain generators of `ablation.GENERATORS` (8 tasks × 3
demonstrations) and the published families of `benchmarks.families.FAMILIES` at their smaller demonstration
count (the multi-task forms: 8 goal tasks × 3; objectworld single-task: 16 paths of 8 steps), the frozen
ones only reported. For each task reward, the learned reward is put on the true reward's scale by a least-squares
affine fit (its level and scale are not identified) and its absolute error taken per state; the Spearman
correlation of an estimate with that error is taken over every task's states but its goal, pooled. Estimates:
the spread (`FitResult.reward_spread`), and the graph distance (hops, `demo_distance`) to the nearest state
the task's demonstrations visit. The spread is also correlated with the absolute difference between the
fit and a second default fit of seed `REFIT_SEED` (other initial weights, other folds; affine-aligned the
same way): what a spread across members estimates is that variability; and the two fits' absolute errors
with each other: where they agree, the error is one every fit makes, which no spread across fits can show.
"|truth − mean|" correlates the error with the true reward's own distance from its mean: not an estimate
(it needs the truth) but what ranks the error where the learned reward explains little of the truth. "Best
function of the reward" is a bound on any estimate read off the learned reward alone: the error's mean per
decile of the (per task standardised) learned reward, chosen with the truth on the same states, and the
decile where that mean peaks. The
baseline likewise against the world's reward (terrain: −cost). Also the mean absolute error by evidence
(`metairl_engine.evidence`: visited, next to a visit, elsewhere). The run's rows with their provenance
replace ``uncertainty_results.json`` beside this script (the results page reads it). Usage::

    .venv/bin/python -m benchmarks.uncertainty [--worlds 3] [--families repo multi-objectworld …]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp
import torch
from scipy.sparse.csgraph import dijkstra
from scipy.stats import spearmanr

from benchmarks.ablation import GENERATORS
from benchmarks.families import FAMILIES, tasks_of
from benchmarks.provenance import provenance
from metairl_engine import FitConfig
from metairl_engine.demos import Trajectory
from metairl_engine.evidence import NEXT_TO_VISITED, VISITED, evidence
from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix
from metairl_engine.results import TaskData
from metairl_engine.sim.terrain import SimTask

RESULTS = Path(__file__).resolve().parent / "uncertainty_results.json"
N_TASKS, N_DEMOS = 8, 3
"""Tasks and demonstrations per task of a terrain world (the families bring their own)."""

ROWS = (
    *GENERATORS,
    "multi-objectworld",
    "multi-binaryworld",
    "objectworld",
    "multi-objectworld-discrete (frozen)",
    "multi-gridworld (frozen)",
)
"""The table's families, in order: terrain generators, then the published families (the frozen ones last)."""

REFIT_SEED = 1
"""Seed of the second default fit per world, whose difference from the first the spread should predict."""

ESTIMATES = ("spread", "hops", "truth_offset")
"""Per-state quantities correlated with the absolute error (see the module docstring)."""


def absolute_error(learned: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """|a·learned + b − truth| on ``mask`` with (a, b) the least-squares fit there."""
    x, y = learned[mask].astype(np.float64), truth[mask].astype(np.float64)
    a, b = np.polyfit(x, y, 1)
    return np.abs(a * x + b - y)


REWARD_BINS = 10
"""Quantile bins of the standardised learned reward for the best-function bound (deciles)."""


def binned_error(reward_z: np.ndarray, error: np.ndarray) -> tuple[np.ndarray, int]:
    """Per state, the mean ``error`` of its decile of ``reward_z`` (in-sample, so an upper bound on what a
    function of the reward can rank), and the decile (0 lowest) where that mean is highest."""
    edges = np.quantile(reward_z, np.linspace(0, 1, REWARD_BINS + 1)[1:-1])
    decile = np.searchsorted(edges, reward_z, side="right")
    means = np.array([error[decile == b].mean() if (decile == b).any() else 0.0 for b in range(REWARD_BINS)])
    return means[decile], int(means.argmax())


def demo_distance(mdp: MDP, trajectories: list[Trajectory]) -> np.ndarray:
    """Per state, the fewest moves (either way round, any action) to a state ``trajectories`` visit."""
    p = transition_matrix(mdp).tocoo()
    graph = sp.csr_matrix((np.ones(p.nnz), (p.row // mdp.n_actions, p.col)), shape=(mdp.n_states,) * 2)
    visited = np.unique(np.concatenate([np.asarray(t.states) for t in trajectories]))
    return np.asarray(dijkstra(graph + graph.T, unweighted=True, indices=visited, min_only=True))


SINGLE_TASK_DEMOS = 16
"""Paths of 8 steps in a single-task family's fit (its families-table counts run from 4 to 128)."""


def world_of(family: str, index: int) -> tuple[MDP, list[SimTask], np.ndarray]:
    """World ``index`` of ``family``: its MDP, its tasks, and the baseline's truth."""
    if family in GENERATORS:
        world, sims = GENERATORS[family](index)
        sims = [replace(s, trajectories=s.trajectories[:N_DEMOS]) for s in sims[:N_TASKS]]
        return world.mdp, sims, -world.cost
    spec = FAMILIES[family]
    reward_world = spec.world(index)
    n_demos = spec.demos[0] if spec.multi else SINGLE_TASK_DEMOS
    return reward_world.mdp, tasks_of(spec, reward_world, index, n_demos), reward_world.reward


def score_world(family: str, index: int) -> dict[str, Any]:
    """One default fit on world ``index``: pooled Spearman of each estimate with |error|, and more."""
    from metairl_engine.fit import fit

    mdp, sims, base_truth = world_of(family, index)
    tasks = [TaskData(mdp, s.trajectories, s.name) for s in sims]
    started = time.process_time()
    result = fit(tasks, FitConfig())
    cpu = time.process_time() - started
    refit = fit(tasks, FitConfig(seed=REFIT_SEED))
    assert result.reward_spread is not None and result.baseline_spread is not None
    pooled: dict[str, list[np.ndarray]] = {
        k: [] for k in ("error", "refit", "refit_error", "reward_z", *ESTIMATES)
    }
    errors: dict[float, list[np.ndarray]] = {VISITED: [], NEXT_TO_VISITED: [], 0.0: []}
    pearsons = []
    for i, sim in enumerate(sims):
        mask = np.arange(mdp.n_states) != sim.goal
        error = absolute_error(result.rewards[i], sim.true_reward, mask)
        truth = sim.true_reward[mask]
        pearsons.append(float(np.corrcoef(result.rewards[i][mask], truth)[0, 1]))
        pooled["error"].append(error)
        pooled["refit"].append(absolute_error(refit.rewards[i], result.rewards[i], mask))
        pooled["refit_error"].append(absolute_error(refit.rewards[i], sim.true_reward, mask))
        pooled["spread"].append(result.reward_spread[i][mask])
        pooled["hops"].append(demo_distance(mdp, sim.trajectories)[mask])
        pooled["truth_offset"].append(np.abs(truth - truth.mean()))
        learned = result.rewards[i][mask].astype(np.float64)
        pooled["reward_z"].append((learned - learned.mean()) / learned.std())
        seen = evidence(mdp, sim.trajectories)[mask]
        for level, found in errors.items():
            found.append(error[seen == level])
    error = np.concatenate(pooled["error"])
    best, peak = binned_error(np.concatenate(pooled["reward_z"]), error)
    every = np.ones(mdp.n_states, dtype=bool)
    base_error = absolute_error(result.baseline, base_truth, every)
    return {
        "family": family,
        "world": index,
        "pearson": float(np.mean(pearsons)),
        **{f"rho_{k}": float(spearmanr(np.concatenate(pooled[k]), error)[0]) for k in ESTIMATES},
        "rho_baseline": float(spearmanr(result.baseline_spread, base_error)[0]),
        "rho_best_of_reward": float(spearmanr(best, error)[0]),
        "error_peak_decile": peak,
        "rho_error_refit_error": float(spearmanr(error, np.concatenate(pooled["refit_error"]))[0]),
        "rho_spread_refit": float(
            spearmanr(np.concatenate(pooled["spread"]), np.concatenate(pooled["refit"]))[0]
        ),
        **{
            f"error_{level}": float(np.concatenate(found).mean()) if sum(map(len, found)) else None
            for level, found in errors.items()
        },
        "cpu_seconds": cpu,
    }


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown: a row per family, means over its worlds."""
    lines = [
        "| family | worlds | Pearson | Spearman(spread, abs error) | Spearman(hops to a demo, abs error) | "
        "baseline: Spearman(spread, abs error) | Spearman(abs(truth − mean), abs error) | Spearman(best function "
        "of the reward, abs error) | its peak: decile of the reward | Spearman(spread, abs difference from a "
        "refit) | Spearman(abs error, the refit's abs error) | abs error visited / next to a visit / elsewhere | "
        "CPU s per fit |",
        "| --- " * 13 + "|",
    ]
    for family in dict.fromkeys(r["family"] for r in rows):
        sel = [r for r in rows if r["family"] == family]

        def mean(key: str, sel: list[dict[str, Any]] = sel) -> float:
            return float(np.mean([r[key] for r in sel if r[key] is not None]))

        peaks = "/".join(str(r["error_peak_decile"]) for r in sel)

        lines.append(
            f"| {family} | {len(sel)} | {mean('pearson'):.3f} | {mean('rho_spread'):+.2f} | {mean('rho_hops'):+.2f} "
            f"| {mean('rho_baseline'):+.2f} | {mean('rho_truth_offset'):+.2f} | {mean('rho_best_of_reward'):+.2f} | {peaks} "
            f"| {mean('rho_spread_refit'):+.2f} | {mean('rho_error_refit_error'):+.2f} | {mean(f'error_{VISITED}'):.3f} / "
            f"{mean(f'error_{NEXT_TO_VISITED}'):.3f} / {mean('error_0.0'):.3f} | {mean('cpu_seconds'):.1f} |"
        )
    return "\n".join(lines)


def main() -> None:
    """Score every family's first ``--worlds`` worlds; store the rows and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--worlds", type=int, default=3)
    parser.add_argument("--families", nargs="+", default=list(ROWS), choices=list(ROWS))
    args = parser.parse_args()
    torch.set_num_threads(1)
    run = provenance()
    rows = []
    for family in args.families:
        for k in range(args.worlds):
            rows.append(score_world(family, k))
            print(json.dumps(rows[-1]), flush=True)
    RESULTS.write_text(json.dumps({"provenance": run, "rows": rows}, indent=1) + "\n")
    print(table(rows))


if __name__ == "__main__":
    main()
