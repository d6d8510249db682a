"""Scale benchmark: the paper's 100×100 × 8-direction motion MDP (80,000 states, 8 actions).

Measures, for meta-IRL with Huber sharing on all states and the default MLP [100, 50, 25]:
seconds per optimisation step and peak RSS for 1, 4, 8, 16 tasks (each in a fresh process, so RSS is
that fit's alone); steps, wall time and accuracy (mean Pearson of each task's reward with its true
reward, on all states and on the states its demonstrations visited) to the default stopping rule for 8
and 16 tasks; and the MaxEnt reference solver's time per task on the same MDP. ``--blocks`` repeats the
step and full rows for each value of `FitConfig.sharing_blocks` (0: automatic, 1: every state every
step). The rows and their provenance go to ``benchmarks/scale_results.json`` (``--results``). Usage::

    python -m benchmarks.scale [--tasks 1 4 8 16] [--steps 10] [--full 8 16] [--maxent 1] [--threads N] [--blocks 0 1]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.provenance import provenance
from metairl_engine import FitConfig, Trajectory
from metairl_engine.grids import grid_mdp
from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix, value_iteration
from metairl_engine.results import TaskData
from metairl_engine.sim.terrain import make_world

ROOT = Path(__file__).resolve().parents[1]

SIZE = 100
CONFIG = FitConfig(sharing="huber", sharing_states="all")


def motion_reward(goal_cell: int, *, seed: int) -> np.ndarray:
    """The true reward of the motion task to ``goal_cell``: −terrain cost (the same in every direction
    channel) plus a bonus of 3 in the goal cell's 8 direction states."""
    reward = -np.tile(make_world(size=SIZE, n_hills=12, seed=seed).cost, 8).astype(np.float64)
    reward[goal_cell :: SIZE * SIZE] += 3.0
    return reward


def motion_goal(task: TaskData) -> int:
    """The goal cell of a `motion_tasks` task (its name says it)."""
    return int(task.name.removeprefix("goal "))


def motion_tasks(n_tasks: int, *, n_demos: int = 3, seed: int = 0) -> list[TaskData]:
    """Tasks on the velocity grid: reward = `motion_reward` of a random goal cell, soft-optimal demonstrations."""
    mdp: MDP = grid_mdp(width=SIZE, height=SIZE, velocity=True, gamma=0.9)
    assert mdp.next_state is not None
    p = transition_matrix(mdp)
    rng = np.random.default_rng(seed)
    cells = SIZE * SIZE
    tasks = []
    for _ in range(n_tasks):
        goal_cell = int(rng.integers(cells))
        reward = motion_reward(goal_cell, seed=seed)
        policy = value_iteration(p, reward, gamma=mdp.gamma, confidence=2.0, tolerance=1e-4).policy
        demos = []
        for _ in range(n_demos):
            states, actions = [int(rng.integers(mdp.n_states))], list[int]()
            while states[-1] % cells != goal_cell and len(actions) < 150:
                a = int(rng.choice(mdp.n_actions, p=policy[states[-1]]))
                actions.append(a)
                states.append(int(mdp.next_state[states[-1], a]))
            if not actions:  # started on the goal cell: take one step
                actions.append(0)
                states.append(int(mdp.next_state[states[-1], 0]))
            demos.append(Trajectory.of(states, actions))
        tasks.append(TaskData(mdp=mdp, trajectories=demos, name=f"goal {goal_cell}"))
    return tasks


def accuracy(tasks: list[TaskData], rewards: np.ndarray) -> tuple[float, float]:
    """Mean Pearson of each task's learned reward with its true one: on all states, on its visited states."""
    everywhere, visited = [], []
    for task, learned in zip(tasks, rewards, strict=True):
        true = motion_reward(motion_goal(task), seed=0)
        seen = np.unique(np.concatenate([tr.states for tr in task.trajectories]))
        everywhere.append(np.corrcoef(learned, true)[0, 1])
        visited.append(np.corrcoef(learned[seen], true[seen])[0, 1])
    return float(np.mean(everywhere)), float(np.mean(visited))


def child(mode: str, n_tasks: int, steps: int, threads: int, blocks: int) -> dict[str, float]:
    """Run one measurement in this process and return its numbers (called in a fresh subprocess)."""
    import torch

    if threads:
        torch.set_num_threads(threads)

    from metairl_engine.fit import fit

    config = replace(CONFIG, sharing_blocks=blocks)
    tasks = motion_tasks(n_tasks)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    times: list[tuple[float, float]] = []
    if mode == "step":
        fit(tasks, replace(config, max_steps=2, holdout_fraction=0.0))  # warm-up
        result = fit(
            tasks,
            replace(config, max_steps=steps, holdout_fraction=0.0, tolerance=0.0),
            progress=lambda p: times.append((p.elapsed_s, time.process_time())),
        )
        wall, cpu = np.diff(np.array(times), axis=0).T
        per_step = float(np.median(wall))
        out = {
            "s_per_step": per_step,
            "s_per_task_step": per_step / n_tasks,
            "cpu_s_per_step": float(np.median(cpu)),
            "steps": len(result.history),
            "load_average": os.getloadavg()[0],
        }
    elif mode == "full":
        started = time.perf_counter()
        result = fit(tasks, config)
        everywhere, visited = accuracy(tasks, result.rewards)
        out = {
            "steps": len(result.history),
            "kept_step": result.best_step,
            "wall_s": time.perf_counter() - started,
            "pearson_all": everywhere,
            "pearson_visited": visited,
        }
    else:
        started = time.perf_counter()
        result = fit(tasks, replace(config, method="maxent"))
        out = {"s_per_task": (time.perf_counter() - started) / n_tasks, "iterations": len(result.history)}
    out["peak_rss_gb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2
    out["rss_before_fit_gb"] = rss_before / 1024
    out["threads"] = torch.get_num_threads()
    return out


def measure(mode: str, n_tasks: int, steps: int, threads: int, blocks: int = 0) -> dict[str, float]:
    """Run `child` in a fresh interpreter so peak RSS belongs to this measurement only."""
    cmd = [sys.executable, "-m", "benchmarks.scale", "--child", mode, str(n_tasks), str(steps), str(threads)]
    done = subprocess.run([*cmd, str(blocks)], capture_output=True, text=True, check=True, cwd=ROOT)
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> None:
    """Parse arguments, run the measurements, print a markdown table and store the rows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, nargs="*", default=[1, 4, 8, 16])
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--full", type=int, nargs="*", default=[8, 16])
    parser.add_argument("--maxent", type=int, default=1, help="tasks for the MaxEnt timing (0 skips)")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    parser.add_argument(
        "--blocks", type=int, nargs="*", default=[0], help="sharing_blocks values (0: automatic)"
    )
    parser.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "scale_results.json")
    parser.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        mode, n_tasks, steps, threads, blocks = args.child
        print(json.dumps(child(mode, int(n_tasks), int(steps), int(threads), int(blocks))))
        return
    print(
        "| measurement | sharing_blocks | tasks | s/step (CPU s/step) | s/task-step | steps (kept) | wall s "
        "| Pearson all (visited) | peak RSS GB | load |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    run = provenance()
    rows: list[dict[str, Any]] = []
    for blocks in args.blocks:
        for n in args.tasks:
            r = measure("step", n, args.steps, args.threads, blocks)
            rows.append({"measurement": "step time", "sharing_blocks": blocks, "tasks": n, **r})
            print(
                f"| step time | {blocks} | {n} | {r['s_per_step']:.3f} ({r['cpu_s_per_step']:.3f}) "
                f"| {r['s_per_task_step']:.3f} | | | | {r['peak_rss_gb']:.2f} | {r['load_average']:.1f} |",
                flush=True,
            )
        for n in args.full:
            r = measure("full", n, 0, args.threads, blocks)
            rows.append({"measurement": "to stopping rule", "sharing_blocks": blocks, "tasks": n, **r})
            print(
                f"| to stopping rule | {blocks} | {n} | | | {r['steps']} ({r['kept_step']}) | {r['wall_s']:.0f} "
                f"| {r['pearson_all']:.3f} ({r['pearson_visited']:.3f}) | {r['peak_rss_gb']:.2f} "
                f"| {os.getloadavg()[0]:.1f} |",
                flush=True,
            )
    if args.maxent:
        r = measure("maxent", args.maxent, 0, args.threads)
        rows.append({"measurement": "maxent", "tasks": args.maxent, **r})
        print(
            f"| maxent | | {args.maxent} | | {r['s_per_task']:.1f} s/task | {r['iterations']} | | "
            f"| {r['peak_rss_gb']:.2f} | {os.getloadavg()[0]:.1f} |",
            flush=True,
        )
    args.results.write_text(json.dumps({"provenance": run, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
