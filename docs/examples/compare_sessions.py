"""Compare two sessions of one person (e.g. stimulated and unstimulated) from their finished jobs, with the lab client.

    python docs/examples/compare_sessions.py JOB_A JOB_B --url URL --key KEY [--states visited] [--out DIR]

Each job fitted one demonstrator — one session. The script pairs the two baselines and every task that has
the same name in both jobs, compares each pair by reward id (`Client.compare`, ``POST /v1/comparisons``),
prints Pearson, Spearman and the EPIC distance, and with ``--out`` saves each job's comparison matrix as a
PNG. It needs only ``metairl_client`` (httpx and numpy); an error answer of the service stops it with the
problem's title, detail and field errors (`MetairlError`).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from metairl_client import Client, MetairlError


def session_rewards(lab: Client, job_id: str) -> dict[str, str]:
    """A finished job's reward ids by label: ``baseline`` and each task's name."""
    ids = lab.job_rewards(job_id)
    return {"baseline": ids.baseline} | {ids.task_names[t]: r for t, r in ids.tasks.items()}


def compare_sessions(lab: Client, job_a: str, job_b: str, *, states: str = "all") -> list[dict[str, Any]]:
    """One row per label both jobs have (baseline first): the comparison of session a's reward with b's."""
    a, b = session_rewards(lab, job_a), session_rewards(lab, job_b)
    return [
        {"label": label} | lab.compare(a[label], b[label], states=states)
        for label in [n for n in a if n in b]
    ]


def save_matrices(lab: Client, job_ids: list[str], out: Path) -> list[Path]:
    """Each job's comparison matrix (baseline and tasks, pairwise Pearson) as ``<job id>-matrix.png``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for job_id in job_ids:
        path = out / f"{job_id}-matrix.png"
        path.write_bytes(lab.comparison_matrix_png(job_id))
        paths.append(path)
    return paths


def main() -> None:
    """Parse the arguments, print the comparison table and save the matrices."""
    parser = argparse.ArgumentParser(description="compare the rewards of two sessions (two finished jobs)")
    parser.add_argument("job_a")
    parser.add_argument("job_b")
    parser.add_argument("--states", choices=("all", "visited"), default="all")
    parser.add_argument("--out", type=Path, help="save each job's comparison matrix PNG here")
    parser.add_argument("--url", default=os.environ.get("METAIRL_URL", "http://127.0.0.1:8000"))
    parser.add_argument("--key", default=os.environ.get("METAIRL_API_KEY"))
    args = parser.parse_args()
    if not args.key:
        sys.exit("give --key or set METAIRL_API_KEY (scripts/serve.sh prints one)")
    try:
        with Client(args.url, args.key) as lab:
            rows = compare_sessions(lab, args.job_a, args.job_b, states=args.states)
            print(f"{'reward':20s} {'pearson':>8s} {'spearman':>8s} {'EPIC':>6s} {'states':>7s}")
            for row in rows:
                print(
                    f"{row['label'][:20]:20s} {row['pearson']:+8.3f} {row['spearman']:+8.3f} "
                    f"{row['epic_distance']:6.3f} {row['n_compared']:7d}"
                )
            if args.out:
                for path in save_matrices(lab, [args.job_a, args.job_b], args.out):
                    print("wrote", path)
    except MetairlError as error:
        sys.exit(str(error))


if __name__ == "__main__":
    main()
