"""Motion analysis against a running metairl service (docs/tutorial-motion.md), with the lab client.

Two steps, each a sub-command:

    python docs/examples/motion_tutorial.py simulate --out patient/          # the synthetic patient as CSV
    python docs/examples/motion_tutorial.py run --data patient/ --url URL --key KEY

``simulate`` writes ``unstimulated.csv`` and ``stimulated.csv`` (columns t,x,y,instruction at 100 Hz) and
``ideal_reward.csv`` (one value per velocity-grid state) — replace them with your own force-plate exports.
``run`` talks to the service through ``metairl_client.Client`` (httpx and numpy only): it creates the velocity
grid MDP, a demonstrator per session, uploads each recording, submits a meta-IRL job per session, waits for
it (a progress bar on stderr), and prints every direction's reward against the ideal reward (the paper's
Table I, on the states the direction's demonstrations visit and on all states) with the fit's time, saving a
heatmap per direction and of the baseline next to the data. An error answer of the service stops it with
the problem's title, detail and field errors (`MetairlError`). ``--size 30`` keeps everything small for a
first try.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
from pathlib import Path
from typing import Any

from metairl_client import Client, JobState, MetairlError

PLATE = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
"""The force plate's rectangle in metres (the synthetic patient's; use your plate's)."""

SESSIONS = ("unstimulated", "stimulated")


def write_patient_csv(folder: Path, *, size: int, seed: int) -> list[Path]:
    """Simulate the patient (numpy only) and write each session's COP samples and the ideal reward as CSV."""
    from metairl_engine.sim.patient import PatientSettings, simulate_patient

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


def upload_session(lab: Client, path: Path, *, mdp_id: str, name: str) -> dict[str, Any]:
    """Create a demonstrator for one session and upload its recording; returns the recording summary."""
    demonstrator_id = lab.create_demonstrator(name=f"patient 1, {name}", metadata={"session": name})
    recording = lab.upload_recording(demonstrator_id, path, mdp_id=mdp_id, bounds=PLATE, name=name)
    print(f"{name}: {recording['n_samples']} samples, segments {recording['segments']}")
    return recording


def run(lab: Client, data: Path, *, size: int, config: dict[str, Any]) -> None:
    """The whole tutorial: MDP, demonstrators, recordings, true rewards, jobs, rewards and comparisons."""
    ideal = [float(row["reward"]) for row in csv.DictReader((data / "ideal_reward.csv").open())]
    mdp_id = lab.create_mdp(
        {"kind": "grid", "name": "force plate", "width": size, "height": size, "velocity": True, "gamma": 0.9}
    )
    mdp = lab.get_mdp(mdp_id)
    print(f"MDP {mdp_id}: {mdp['n_states']} states × {mdp['n_actions']} actions")
    jobs = {}
    for name in SESSIONS:
        recording = upload_session(lab, data / f"{name}.csv", mdp_id=mdp_id, name=name)
        labels = {t["task_id"]: t["label"] for t in recording["tasks"]}
        for task_id in labels:  # the ideal reward as each task's "truth": truth_pearson is Table I's number
            lab.put_true_reward(task_id, ideal)
        job = lab.submit_job(recording["demonstrator_id"], config=config)
        jobs[name] = (job.id, labels)
    for name, (job_id, labels) in jobs.items():
        job = lab.wait(job_id)
        if job.status != "succeeded":
            print(f"{name}: job {job.status}: {job.error}")
            continue
        print_table_row(lab, data, name=name, job=job, labels=labels, ideal=ideal)


def pearson_with(lab: Client, reward_id: str, values: list[float]) -> tuple[float, float]:
    """Pearson of a reward with ``values`` on the states its demonstrations visit, and on all states."""
    visited = float(lab.compare(reward_id, values, states="visited")["pearson"])
    return visited, float(lab.compare(reward_id, values, states="all")["pearson"])


def print_table_row(
    lab: Client, data: Path, *, name: str, job: JobState, labels: dict[str, str], ideal: list[float]
) -> None:
    """Print a session's Table I row (visited / all states) and its fit time; save a heatmap per reward."""
    assert job.started_at is not None and job.finished_at is not None
    print(f"\n{name}: fit in {(job.finished_at - job.started_at).total_seconds():.0f} s ({job.step} steps)")
    print(f"  Pearson with the ideal reward on {'visited states':>14s} / all states")
    rewards = lab.job_rewards(job.id)
    named = [(labels[task_id], reward_id) for task_id, reward_id in rewards.tasks.items()]
    for label, reward_id in [*named, ("origin", rewards.baseline)]:
        visited, everywhere = pearson_with(lab, reward_id, ideal)
        print(f"  {label:15s} {visited:+.3f} / {everywhere:+.3f}")
        try:
            png = lab.reward_png(reward_id)
        except MetairlError:
            continue
        (data / f"{name}-{label.replace(' ', '-')}.png").write_bytes(png)


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
    try:
        with Client(args.url, args.key, timeout_s=300) as lab:
            run(lab, args.data, size=args.size, config=config)
    except MetairlError as error:
        sys.exit(str(error))


if __name__ == "__main__":
    main()
