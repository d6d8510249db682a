"""The worker's memory estimate (`metairl_engine.memory.fit_memory`) against the measured peak of real fits.

Each case runs in a fresh Python process: it builds a grid or ring MDP and random demonstrations, fits 3
steps (memory peaks in the first step and the final evaluation, not later), and reports the process's peak
resident memory (``ru_maxrss``) above what it held before importing torch, beside the estimate::

    python -m benchmarks.memory            # ten cases, 2-6 minutes on two busy cores
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path
from typing import Any

CASES: list[dict[str, Any]] = [
    {"size": 100, "tasks": 4},
    {"size": 2000, "tasks": 2, "ring": True},
    {"size": 60, "tasks": 2, "tabular": True, "config": {"hidden": [1024, 1024]}},
    {"size": 200, "tasks": 2, "config": {"fourier_octaves": 4, "hidden": [256, 256]}},
    {"size": 100, "tasks": 8, "config": {"ensemble": 4}},
    {"size": 300, "tasks": 16, "config": {"ensemble": 2}},
    {"size": 50, "tasks": 4, "config": {"hidden": [2048, 2048]}},
    {"size": 150, "tasks": 4, "slip": 0.2, "config": {"ensemble": 2}},
    {"size": 100, "tasks": 3, "config": {"method": "maxent"}},
    {"size": 100, "tasks": 4, "config": {"sharing_states": "visited", "ensemble": 2}},
]
"""Grids of size × size cells (``tabular``: without features; ``slip``: stochastic) or a ring of ``size``
states; ``config`` is added to a 3-step fit's."""

MIB = 1024 * 1024


def peak() -> int:
    """This process's peak resident memory in bytes."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def measure(case: dict[str, Any]) -> dict[str, Any]:
    """Fit one case in this process: its sizes, measured peak and estimate."""
    import dataclasses

    import numpy as np

    from metairl_engine import MDP, FitConfig, Trajectory
    from metairl_engine.grids import grid_mdp
    from metairl_engine.memory import fit_memory
    from metairl_engine.planning import transition_matrix
    from metairl_engine.results import TaskData

    before = peak()
    n = case["size"]
    if case.get("ring"):
        mdp = MDP.build(gamma=0.9, next_state=np.array([[(s - 1) % n, (s + 1) % n] for s in range(n)]))
    else:
        mdp = grid_mdp(width=n, height=n, stay=True, slip=case.get("slip", 0.0), gamma=0.9)
    if case.get("tabular"):
        mdp = dataclasses.replace(mdp, features=None)
    p = transition_matrix(mdp)
    rng = np.random.default_rng(0)
    tasks = []
    for t in range(case["tasks"]):
        trajectories = []
        for _ in range(20):
            states, actions = [int(rng.integers(mdp.n_states))], []
            for _ in range(50):
                actions.append(int(rng.integers(mdp.n_actions)))
                row = p[states[-1] * mdp.n_actions + actions[-1]]
                states.append(int(row.indices[np.argmax(row.data)]))
            trajectories.append(Trajectory.of(states, actions))
        tasks.append(TaskData(mdp=mdp, trajectories=trajectories, name=str(t)))
    config = FitConfig(**{"max_steps": 3, "patience": 0, "tolerance": 0, **case.get("config", {})})
    estimate = fit_memory(
        config,
        n_tasks=len(tasks),
        n_states=mdp.n_states,
        n_actions=mdp.n_actions,
        n_features=None if mdp.features is None else mdp.features.shape[1],
        n_steps=sum(len(tr.actions) for task in tasks for tr in task.trajectories),
        n_mdps=1,
        successors=p.nnz / (mdp.n_states * mdp.n_actions),
    )
    import torch

    from metairl_engine.fit import fit

    torch.set_num_threads(1)
    fit(tasks, config)
    return {"states": mdp.n_states, "measured": peak() - before, "estimate": estimate.total}


def main() -> None:
    """Run every case in its own process and print a table (MiB); with a case as JSON, measure just that one."""
    if len(sys.argv) > 1:
        print(json.dumps(measure(json.loads(sys.argv[1]))))
        return
    print("| case | states | measured peak (MiB) | estimate (MiB) | estimate / measured |")
    print("| --- | --- | --- | --- | --- |")
    for case in CASES:
        out = subprocess.run(
            [sys.executable, "-m", "benchmarks.memory", json.dumps(case)],
            capture_output=True,
            text=True,
            check=True,
            cwd=Path(__file__).resolve().parents[1],
        )
        row = json.loads(out.stdout.splitlines()[-1])
        ratio = row["estimate"] / row["measured"]
        print(
            f"| `{json.dumps(case)}` | {row['states']:,} | {row['measured'] / MIB:,.0f} | "
            f"{row['estimate'] / MIB:,.0f} | {ratio:.2f} |"
        )


if __name__ == "__main__":
    main()
