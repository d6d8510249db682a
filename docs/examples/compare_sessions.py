"""Compare two sessions of one person (e.g. stimulated and unstimulated) from their finished jobs, with httpx only.

    python docs/examples/compare_sessions.py JOB_A JOB_B --url URL --key KEY [--states visited] [--out DIR]

Each job fitted one demonstrator — one session. The script pairs the two baselines and every task that has
the same name in both jobs, compares each pair by reward id (``POST /v1/comparisons``), prints Pearson,
Spearman and the EPIC distance, and with ``--out`` saves each job's comparison matrix as a PNG.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import httpx


def ok(response: httpx.Response) -> Any:
    """The JSON of a successful response; otherwise stop with the problem document."""
    if response.is_error:
        sys.exit(
            f"{response.request.method} {response.request.url} → {response.status_code}\n{response.text}"
        )
    return response.json()


def session_rewards(api: httpx.Client, job_id: str) -> dict[str, str]:
    """A finished job's reward ids by label: ``baseline`` and each task's name."""
    listing = ok(api.get(f"/v1/jobs/{job_id}/rewards"))
    return {"baseline": listing["baseline"]["reward_id"]} | {
        t["task_name"]: t["reward_id"] for t in listing["tasks"]
    }


def compare_sessions(
    api: httpx.Client, job_a: str, job_b: str, *, states: str = "all"
) -> list[dict[str, Any]]:
    """One row per label both jobs have (baseline first): the comparison of session a's reward with b's."""
    a, b = session_rewards(api, job_a), session_rewards(api, job_b)
    rows = []
    for label in [name for name in a if name in b]:
        body = {"a": {"reward_id": a[label]}, "b": {"reward_id": b[label]}, "states": states}
        rows.append({"label": label} | ok(api.post("/v1/comparisons", json=body)))
    return rows


def save_matrices(api: httpx.Client, job_ids: list[str], out: Path) -> list[Path]:
    """Each job's comparison matrix (baseline and tasks, pairwise Pearson) as ``<job id>-matrix.png``."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for job_id in job_ids:
        response = api.get(f"/v1/jobs/{job_id}/comparison-matrix", params={"format": "png"})
        if response.is_error:
            ok(response)
        path = out / f"{job_id}-matrix.png"
        path.write_bytes(response.content)
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
    with httpx.Client(base_url=args.url, headers={"Authorization": f"Bearer {args.key}"}, timeout=60) as api:
        rows = compare_sessions(api, args.job_a, args.job_b, states=args.states)
        print(f"{'reward':20s} {'pearson':>8s} {'spearman':>8s} {'EPIC':>6s} {'states':>7s}")
        for row in rows:
            print(
                f"{row['label'][:20]:20s} {row['pearson']:+8.3f} {row['spearman']:+8.3f} "
                f"{row['epic_distance']:6.3f} {row['n_compared']:7d}"
            )
        if args.out:
            for path in save_matrices(api, [args.job_a, args.job_b], args.out):
                print("wrote", path)


if __name__ == "__main__":
    main()
