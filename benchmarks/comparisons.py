"""What a job's comparison matrix costs the API process: EPIC with dynamics between every pair of a job's rewards
(`metairl_engine.distances.pairwise_epic`, what ``GET /v1/jobs/{id}/comparison-matrix`` computes), on velocity
grids up to the paper's 100×100 × 8 directions (80,000 states).

Each case runs in a fresh Python process: it builds the grid's transitions and k random rewards (a job of
k − 1 tasks and its baseline), computes the matrix, and reports wall and CPU seconds and the process's peak
resident memory above what it held before (``ru_maxrss``): the request's share of the API's memory. The run's
rows with their provenance replace ``comparisons_results.json`` beside this script. Usage::

    python -m benchmarks.comparisons            # four cases, about a minute
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.provenance import provenance

RESULTS = Path(__file__).resolve().parent / "comparisons_results.json"
CASES: list[dict[str, Any]] = [
    {"size": 30, "gamma": 0.9, "rewards": 9},
    {"size": 100, "gamma": 0.9, "rewards": 9},
    {"size": 100, "gamma": 0.99, "rewards": 9},
    {"size": 100, "gamma": 0.9, "rewards": 17},
]
"""Velocity grids of size × size cells × 8 directions, their discount, and the rewards compared pairwise."""
MIB = 1024 * 1024


def child(case: dict[str, Any]) -> dict[str, Any]:
    """One case in this process: the matrix's seconds and the memory it added."""
    import numpy as np

    from metairl_engine.distances import pairwise_epic
    from metairl_engine.grids import grid_mdp
    from metairl_engine.planning import transition_matrix

    mdp = grid_mdp(width=case["size"], height=case["size"], velocity=True, gamma=case["gamma"])
    transitions = transition_matrix(mdp)
    rng = np.random.default_rng(0)
    rewards = [rng.normal(size=mdp.n_states).astype(np.float32) for _ in range(case["rewards"])]
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    wall, cpu = time.perf_counter(), time.process_time()
    pairwise_epic(rewards, transitions=transitions, gamma=mdp.gamma, n_actions=mdp.n_actions)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {**case, "states": mdp.n_states, "wall_s": wall, "cpu_s": cpu, "added_mib": (after - before) / MIB}


def measure(case: dict[str, Any]) -> dict[str, Any]:
    """`child` run in a fresh process, so its peak memory is the case's own."""
    out = subprocess.run(
        [sys.executable, "-m", "benchmarks.comparisons", "--child", json.dumps(case)],
        capture_output=True,
        text=True,
        check=True,
    )
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def main() -> None:
    """Run every case, store the rows and print them."""
    if len(sys.argv) == 3 and sys.argv[1] == "--child":
        print(json.dumps(child(json.loads(sys.argv[2]))))
        return
    run = provenance()
    rows = []
    for case in CASES:
        rows.append(measure(case))
        print(json.dumps(rows[-1]), flush=True)
    RESULTS.write_text(json.dumps({"provenance": run, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
