"""Does the reward's spread across the ensemble's members say where the learned reward is wrong?

On worlds of each terrain generator of `ablation.GENERATORS` (the repo's, the frozen one, the slippery one),
one default fit of 8 tasks × 3 demonstrations; for each task reward, the learned reward is put on the true
reward's scale by a least-squares affine fit (its level and scale are not identified), and the Spearman
correlation between the spread (`FitResult.reward_spread`) and the absolute error is taken over the states
other than the goal; the baseline likewise against −cost; "relative spread" divides the spread by the
state's distance from the reward's mean. Also the mean absolute error by evidence
(`metairl_engine.evidence`: visited, next to a visit, elsewhere). Usage::

    .venv/bin/python -m benchmarks.uncertainty [--worlds 3] [--tasks 8] [--demos 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.stats import spearmanr

from benchmarks.ablation import GENERATORS
from metairl_engine import FitConfig
from metairl_engine.evidence import NEXT_TO_VISITED, VISITED, evidence
from metairl_engine.results import TaskData


def absolute_error(learned: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """|a·learned + b − truth| on ``mask`` with (a, b) the least-squares fit there."""
    x, y = learned[mask].astype(np.float64), truth[mask].astype(np.float64)
    a, b = np.polyfit(x, y, 1)
    return np.abs(a * x + b - y)


def score_world(generator: str, index: int, *, n_tasks: int, n_demos: int) -> dict[str, float]:
    """One fit on world ``index``: Spearman(spread, |error|) over tasks and of the baseline, error by evidence."""
    from metairl_engine.fit import fit

    world, sims = GENERATORS[generator](index)
    chosen = sims[:n_tasks]
    tasks = [TaskData(world.mdp, s.trajectories[:n_demos], s.name) for s in chosen]
    started = time.perf_counter()
    result = fit(tasks, FitConfig())
    wall = time.perf_counter() - started
    assert result.reward_spread is not None and result.baseline_spread is not None
    rhos, relative, errors = [], [], {VISITED: [], NEXT_TO_VISITED: [], 0.0: []}
    for i, (sim, task) in enumerate(zip(chosen, tasks, strict=True)):
        mask = np.arange(world.mdp.n_states) != sim.goal
        error = absolute_error(result.rewards[i], sim.true_reward, mask)
        spread = result.reward_spread[i][mask]
        rhos.append(spearmanr(spread, error)[0])
        # the spread over the state's distance from the reward's mean: where the members cannot tell whether
        # the state is better or worse than average
        offset = np.abs(result.rewards[i][mask] - result.rewards[i][mask].mean())
        relative.append(spearmanr(spread / (offset + 1e-6), error)[0])
        seen = evidence(world.mdp, task.trajectories)[mask]
        for level, found in errors.items():
            found.extend(error[seen == level])
    every = np.ones(world.mdp.n_states, dtype=bool)
    base_error = absolute_error(result.baseline, -world.cost, every)
    return {
        "task_rho": float(np.mean(rhos)),
        "relative_rho": float(np.mean(relative)),
        "baseline_rho": float(spearmanr(result.baseline_spread, base_error)[0]),
        **{f"error_{level}": float(np.mean(found)) if found else np.nan for level, found in errors.items()},
        "wall_s": wall,
    }


def main() -> None:
    """Score every generator's first ``--worlds`` worlds; print a markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--worlds", type=int, default=3)
    parser.add_argument("--tasks", type=int, default=8)
    parser.add_argument("--demos", type=int, default=3)
    parser.add_argument("--generators", nargs="+", default=list(GENERATORS), choices=list(GENERATORS))
    args = parser.parse_args()
    lines = [
        "| generator | worlds | Spearman(spread, abs error), tasks | baseline | relative spread, tasks | abs error "
        "visited / next to a visit / elsewhere | wall s per fit |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for g in args.generators:
        rows = [score_world(g, k, n_tasks=args.tasks, n_demos=args.demos) for k in range(args.worlds)]
        for k, r in enumerate(rows):
            print(g, k, r, flush=True)

        def mean(key: str, rows: list[dict[str, float]] = rows) -> float:
            return float(np.nanmean([r[key] for r in rows]))

        lines.append(
            f"| {g} | {args.worlds} | {mean('task_rho'):+.2f} | {mean('baseline_rho'):+.2f} | "
            f"{mean('relative_rho'):+.2f} | "
            f"{mean(f'error_{VISITED}'):.3f} / {mean(f'error_{NEXT_TO_VISITED}'):.3f} / {mean('error_0.0'):.3f} | "
            f"{mean('wall_s'):.1f} |"
        )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
