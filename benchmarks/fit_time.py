"""CPU seconds and accuracy per default fit (8 tasks × 3 demonstrations) on worlds of both terrain generators.

Times `fit(…, FitConfig())` of whatever engine is importable, so the same command compares engines: run it
in this checkout and, with this checkout's ``benchmarks`` on the path, in a checkout of an earlier commit (its
own ``metairl_engine`` comes first: ``python -m`` puts the working directory first), one after the other, on a
quiet machine. Rows with their provenance go to ``benchmarks/fit_time_results.json`` (``--results``)::

    python -m benchmarks.fit_time --repo 3 --frozen 2
    git worktree add ../before 9038d98 && cd ../before && \\
        PYTHONPATH=../<this checkout> python -m benchmarks.fit_time --repo 3 --frozen 2 --results ../before.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import torch

import metairl_engine
from benchmarks.accuracy import run_one, world_and_tasks
from benchmarks.frozen_terrain import frozen_world_and_tasks
from benchmarks.provenance import git_commit, provenance
from metairl_engine import FitConfig

HERE = Path(__file__).resolve().parent


def main() -> None:
    """Time one default fit per world (``--seed`` aside), print a row each (CPU s, wall s, steps, accuracy)
    and the means, and store the rows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repo", type=int, default=3, help="worlds 0 … N−1 of the repo's generator")
    parser.add_argument("--frozen", type=int, default=2, help="worlds 0 … N−1 of the frozen generator")
    parser.add_argument(
        "--seed", type=int, default=0, help="FitConfig.seed: initial weights and hold-out folds"
    )
    parser.add_argument(
        "--results",
        type=Path,
        default=HERE / "fit_time_results.json",
        help="where this run's rows are stored",
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    print(f"engine: {Path(metairl_engine.__file__).parent}")
    run = {**provenance(), "engine_commit": git_commit(Path(metairl_engine.__file__).parent)}
    stored: list[dict[str, Any]] = []
    for name, make, count in (
        ("repo", world_and_tasks, args.repo),
        ("frozen", frozen_world_and_tasks, args.frozen),
    ):
        rows = []
        for w in range(count):
            world, sims = make(w)
            row = run_one(world, sims, n_tasks=8, n_demos=3, config=FitConfig(seed=args.seed))
            rows.append(row)
            stored.append({"generator": name, "world": w, "seed": args.seed, **row})
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
    args.results.write_text(json.dumps({"provenance": run, "rows": stored}, indent=1) + "\n")


if __name__ == "__main__":
    main()
