"""Motion analysis against a running metairl service (docs/tutorial-motion.md), with httpx only.

Two steps, each a sub-command:

    python docs/examples/motion_tutorial.py simulate --out patient/          # the synthetic patient as CSV
    python docs/examples/motion_tutorial.py run --data patient/ --url URL --key KEY

``simulate`` writes ``unstimulated.csv`` and ``stimulated.csv`` (columns t,x,y,instruction at 100 Hz) and
``ideal_reward.csv`` (one value per velocity-grid state) — replace them with your own force-plate exports.
``run`` creates the velocity grid MDP, a demonstrator per session, uploads each recording, submits a meta-IRL
job per session, waits for it, and prints every direction's reward against the ideal reward (the paper's
Table I, on the states the direction's demonstrations visit and on all states) with the fit's time, saving a
heatmap per direction and of the baseline next to the data. ``--size 30`` keeps everything small for a first try.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx

PLATE = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
"""The force plate's rectangle in metres (the synthetic patient's; use your plate's)."""

SESSIONS = ("unstimulated", "stimulated")
TERMINAL = {"succeeded", "failed", "cancelled"}


def write_patient_csv(folder: Path, *, size: int, seed: int) -> list[Path]:
    """Simulate the patient (numpy only) and write each session's COP samples and the ideal reward as CSV."""
    from metairl_engine.patient import PatientSettings, simulate_patient

    patient = simulate_patient(PatientSettings(width=size, height=size, seed=seed))
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, rec in patient.sessions.items():
        path = folder / f"{name}.csv"
        with path.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["t", "x", "y", "instruction"])
            instruction = rec.instruction if rec.instruction is not None else [""] * len(rec.t)
            writer.writerows(
                (f"{t:.3f}", f"{x:.6f}", f"{y:.6f}", i)
                for t, x, y, i in zip(rec.t, rec.x, rec.y, instruction, strict=True)
            )
        written.append(path)
    ideal = folder / "ideal_reward.csv"
    ideal.write_text("reward\n" + "\n".join(f"{v:.6f}" for v in patient.ideal_reward) + "\n")
    return [*written, ideal]


def ok(response: httpx.Response) -> Any:
    """The JSON of a successful response; otherwise stop with the problem document."""
    if response.is_error:
        sys.exit(
            f"{response.request.method} {response.request.url} → {response.status_code}\n{response.text}"
        )
    return response.json()


def upload_session(api: httpx.Client, path: Path, *, mdp_id: str, name: str) -> dict[str, Any]:
    """Create a demonstrator for one session and upload its recording; returns the recording summary."""
    dem = ok(
        api.post("/v1/demonstrators", json={"name": f"patient 1, {name}", "metadata": {"session": name}})
    )
    with path.open("rb") as handle:
        recording = ok(
            api.post(
                f"/v1/demonstrators/{dem['id']}/recordings",
                files={"file": (path.name, handle, "text/csv")},
                data={"mdp_id": mdp_id, "bounds": json.dumps(PLATE), "name": name},
            )
        )
    print(f"{name}: {recording['n_samples']} samples, segments {recording['segments']}")
    return recording


def wait(api: httpx.Client, job_id: str, *, poll_s: float = 5.0) -> dict[str, Any]:
    """Poll a job until it is finished, printing its progress."""
    while True:
        job = ok(api.get(f"/v1/jobs/{job_id}"))
        progress = job.get("progress") or {}
        print(f"  {job_id}: {job['status']} step {progress.get('step')} loss {progress.get('loss')}")
        if job["status"] in TERMINAL:
            return job
        time.sleep(poll_s)


def run(api: httpx.Client, data: Path, *, size: int, config: dict[str, Any]) -> None:
    """The whole tutorial: MDP, demonstrators, recordings, true rewards, jobs, rewards and comparisons."""
    ideal = [float(row["reward"]) for row in csv.DictReader((data / "ideal_reward.csv").open())]
    mdp = ok(
        api.post(
            "/v1/mdps",
            json={
                "kind": "grid",
                "name": "force plate",
                "width": size,
                "height": size,
                "velocity": True,
                "gamma": 0.9,
            },
        )
    )
    print(f"MDP {mdp['id']}: {mdp['n_states']} states × {mdp['n_actions']} actions")
    jobs = {}
    for name in SESSIONS:
        recording = upload_session(api, data / f"{name}.csv", mdp_id=mdp["id"], name=name)
        labels = {t["task_id"]: t["label"] for t in recording["tasks"]}
        for task_id in labels:  # the ideal reward as each task's "truth": truth_pearson is Table I's number
            ok(api.put(f"/v1/tasks/{task_id}/true-reward", json={"values": ideal}))
        job = ok(
            api.post("/v1/jobs", json={"demonstrator_id": recording["demonstrator_id"], "config": config})
        )
        jobs[name] = (job["id"], labels)
    for name, (job_id, labels) in jobs.items():
        job = wait(api, job_id)
        if job["status"] != "succeeded":
            print(f"{name}: job {job['status']}: {job.get('error')}")
            continue
        print_table_row(api, data, name=name, job=job, labels=labels, ideal=ideal)


def pearson_with(api: httpx.Client, reward_id: str, values: list[float]) -> tuple[float, float]:
    """Pearson of a reward with ``values`` on the states its demonstrations visit, and on all states."""

    def compare(states: str) -> float:
        body = {"a": {"reward_id": reward_id}, "b": {"values": values}, "states": states}
        return float(ok(api.post("/v1/comparisons", json=body))["pearson"])

    return compare("visited"), compare("all")


def print_table_row(
    api: httpx.Client,
    data: Path,
    *,
    name: str,
    job: dict[str, Any],
    labels: dict[str, str],
    ideal: list[float],
) -> None:
    """Print a session's Table I row (visited / all states) and its fit time; save a heatmap per reward."""
    started, finished = (datetime.fromisoformat(job[k]) for k in ("started_at", "finished_at"))
    steps = job["progress"]["step"]
    print(f"\n{name}: fit in {(finished - started).total_seconds():.0f} s ({steps} steps)")
    print(f"  Pearson with the ideal reward on {'visited states':>14s} / all states")
    rewards = ok(api.get(f"/v1/jobs/{job['id']}/rewards"))
    named = [(labels[t["task_id"]], t["reward_id"]) for t in rewards["tasks"]]
    for label, reward_id in [*named, ("origin", rewards["baseline"]["reward_id"])]:
        visited, everywhere = pearson_with(api, reward_id, ideal)
        print(f"  {label:15s} {visited:+.3f} / {everywhere:+.3f}")
        png = api.get(f"/v1/rewards/{reward_id}", params={"format": "png"})
        if png.is_success:
            (data / f"{name}-{label.replace(' ', '-')}.png").write_bytes(png.content)


def main() -> None:
    """Parse the sub-command and run it."""
    parser = argparse.ArgumentParser(description="metairl motion-analysis tutorial")
    commands = parser.add_subparsers(dest="command", required=True)
    simulate = commands.add_parser("simulate", help="write the synthetic patient as CSV")
    simulate.add_argument("--out", type=Path, default=Path("patient"))
    simulate.add_argument("--size", type=int, default=100)
    simulate.add_argument("--seed", type=int, default=0)
    tutorial = commands.add_parser("run", help="upload, fit and compare against a running service")
    tutorial.add_argument("--data", type=Path, default=Path("patient"))
    tutorial.add_argument(
        "--size", type=int, default=100, help="must match the size the CSVs were simulated at"
    )
    tutorial.add_argument("--url", default=os.environ.get("METAIRL_URL", "http://127.0.0.1:8000"))
    tutorial.add_argument("--key", default=os.environ.get("METAIRL_API_KEY"))
    tutorial.add_argument("--max-steps", type=int, help="cap optimisation steps (default: the service's)")
    args = parser.parse_args()
    if args.command == "simulate":
        for path in write_patient_csv(args.out, size=args.size, seed=args.seed):
            print("wrote", path)
        return
    if not args.key:
        sys.exit("give --key or set METAIRL_API_KEY (scripts/serve.sh prints one)")
    config: dict[str, Any] = {"sharing": "huber"} | ({"max_steps": args.max_steps} if args.max_steps else {})
    with httpx.Client(base_url=args.url, headers={"Authorization": f"Bearer {args.key}"}, timeout=300) as api:
        run(api, args.data, size=args.size, config=config)


if __name__ == "__main__":
    main()
