"""CPU seconds and accuracy per default fit (8 tasks × 3 demonstrations) on worlds of both terrain generators.

Times `fit(…, FitConfig())` of whatever engine is importable, so the same command compares engines: run it
in this checkout and in a checkout of an earlier commit, one after the other, on a quiet machine::

    .venv/bin/python benchmarks/fit_time.py --repo 3 --frozen 2
    git worktree add ../before 9038d98 && cd ../before && bash scripts/bootstrap.sh && \\
        .venv/bin/python ../<this checkout>/benchmarks/fit_time.py --repo 3 --frozen 2
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import metairl_engine  # first, from the checkout that runs this (accuracy.py puts its own root on sys.path)

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import torch  # noqa: E402
from accuracy import run_one, world_and_tasks  # noqa: E402
from frozen_terrain import frozen_world_and_tasks  # noqa: E402

from metairl_engine import FitConfig  # noqa: E402


def main() -> None:
    """Time one default fit per world (``--seed`` aside) and print a row each (CPU s, wall s, steps, accuracy),
    then the means."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repo", type=int, default=3, help="worlds 0 … N−1 of the repo's generator")
    parser.add_argument("--frozen", type=int, default=2, help="worlds 0 … N−1 of the frozen generator")
    parser.add_argument(
        "--seed", type=int, default=0, help="FitConfig.seed: initial weights and hold-out folds"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"engine: {Path(metairl_engine.__file__).parent}")
    for name, make, count in (
        ("repo", world_and_tasks, args.repo),
        ("frozen", frozen_world_and_tasks, args.frozen),
    ):
        rows = []
        for w in range(count):
            world, sims = make(w)
            row = run_one(world, sims, n_tasks=8, n_demos=3, config=FitConfig(seed=args.seed))
            rows.append(row)
            print(
                f"{name} world {w}: {row['cpu_seconds']:.1f} CPU s, {row['seconds']:.1f} s, "
                f"{row['steps']} steps, task reward vs truth {row['task_pearson']:.3f}",
                flush=True,
            )
        if rows:
            mean = {k: sum(r[k] for r in rows) / len(rows) for k in ("cpu_seconds", "steps", "task_pearson")}
            print(
                f"{name} mean of {len(rows)}: {mean['cpu_seconds']:.1f} CPU s, {mean['steps']:.0f} steps, "
                f"task reward vs truth {mean['task_pearson']:.3f}",
                flush=True,
            )


if __name__ == "__main__":
    main()
