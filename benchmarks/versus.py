"""Versus others: this engine against imitation's MCE IRL on the same MDPs at ~1,000, 10,000 and 80,000 states.

For each MDP size, 4 tasks × 3 demonstrations per world, fitted by

1. this engine's default (``fit(tasks, FitConfig())``): time per task = fit time / number of tasks; with
   ``--capped-steps N …`` also the default stopped after at most N steps (at 1,024 states), which shows how
   soon the engine's rewards pass imitation's in accuracy;
2. this engine's ``maxent`` reference solver (``FitConfig(method="maxent")``), one task at a time;
3. HumanCompatibleAI imitation's finite-horizon MCE IRL (``imitation.algorithms.mce_irl.MCEIRL``) on a
   ``seals.base_envs.TabularModelPOMDP`` with a dense (S, A, S) transition matrix, one task at a time, in a
   subprocess running another venv's python (imitation pins its own torch and gymnasium).

Accuracy is the Pearson correlation of each learned task reward with its true reward, goal state(s)
excluded (as ``benchmarks.accuracy.run_one`` scores), mean ± std over worlds and tasks.

MDPs: 1,024 states: ``terrain.make_world(size=32)``, 3 worlds; 10,000: ``make_world(size=100)``, 1 world
(both 8 moves + stay, one hill per ~43 cells as in accuracy.py, ``make_tasks`` demonstrations); 80,000:
``scale.motion_tasks`` (100×100 velocity grid, 8 actions), 1 world. At 10,000 and 80,000 states only the
engine's default runs unless ``--maxent-large``.

imitation's MCE IRL (fixed settings, printed with the table): reward net ``BasicRewardNet`` on the same
state features (normalised x, y), state only, hidden layers [100, 50, 25] like the engine's networks;
Adam with imitation's default step 0.01; discount = the MDP's γ (0.9, the demonstrator's); horizon = 2 ×
grid side (64 at 1,024 states: γ^64 ≈ 0.001 of the discounted mass is lost); a fixed number of
iterations (``--imitation-iterations``, default 50: on world 0's first task the correlation was 0.50 after 10,
0.46 after 50, 0.44 after 100 and 0.38 after 300 iterations, so more would cost time without accuracy;
imitation's own stopping thresholds, L∞ occupancy gap ≤ 1e-3 or gradient norm ≤ 1e-4, are never met with
3 demonstrations). Demonstrations are given as imitation's discounted state-occupancy measure of
trajectories cut or padded to the horizon: a demonstration that reached its goal stays there (the
terrain's stay action; the soft-optimal demonstrator mostly stays at the goal bonus); the initial-state
distribution is that of the task's demonstration starts.
Dense transitions need S·A·S·8 bytes (imitation's soft Bellman backup ``T @ V`` is float64, so a float32
matrix is cast to a float64 copy on every backup); sizes past ``--max-dense-gb`` are not run and say so.

Time is wall-clock and CPU seconds of the fits alone (not data generation, not imitation's interpreter
start; imitation's includes building its dense matrix), one thread everywhere. Rows, each with its
provenance, go to ``benchmarks/versus_results.json`` (rows of the sizes run are replaced, others kept), the
table to stdout. The imitation side runs this file as a script under ``.venv-imitation``'s python, which
imports neither this engine nor the ``benchmarks`` package. Commands::

    python3 -m venv .venv-imitation && .venv-imitation/bin/pip install "torch==2.13.0" "imitation==1.0.1"
    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.versus
    # or one size at a time (how versus_results.json was made, imitation from another venv):
    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.versus --sizes 1000 --capped-steps 10 20 40 --imitation-python PATH/TO/bin/python
    OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.versus --sizes 10000 80000 --imitation-python PATH/TO/bin/python
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent

if TYPE_CHECKING:
    from metairl_engine import FitConfig, TaskData

N_TASKS, N_DEMOS = 4, 3
HILLS_PER_CELL = 6 / 256
"""accuracy.py's hill density (6 hills on a 16×16 grid), kept on the larger grids."""
MCE_HIDDEN = (100, 50, 25)
"""imitation's reward net: the engine's default hidden widths, so both learn the same function class."""
MCE_LEARNING_RATE = 0.01
"""Adam's step for imitation's reward net (imitation's default)."""
HORIZON_PER_SIDE = 2
"""imitation's finite horizon, in grid sides (the demonstrations' cap is 3 sides)."""
THREAD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
SIZES = {1000: "1,024 (32×32 terrain)", 10000: "10,000 (100×100 terrain)", 80000: "80,000 (100×100×8 motion)"}
IMITATION = "imitation MCE IRL"


def capped(steps: int) -> str:
    """The method name of this engine's default capped at ``steps`` optimisation steps."""
    return f"engine default, ≤ {steps} steps"


@dataclass(frozen=True)
class Problem:
    """One world's tasks and what scoring needs: each task's true reward and the states scored (goal out)."""

    states: int
    world: int
    side: int
    tasks: list[TaskData]
    true_rewards: list[np.ndarray]
    scored: list[np.ndarray]


def terrain_problem(size: int, world: int) -> Problem:
    """A size×size hilly terrain (seeded by ``world``) with N_TASKS goal tasks of N_DEMOS demonstrations."""
    from metairl_engine import TaskData
    from metairl_engine.sim.terrain import make_tasks, make_world

    terrain = make_world(size=size, n_hills=round(HILLS_PER_CELL * size * size), seed=world)
    sims = make_tasks(terrain, n_tasks=N_TASKS, n_demos=N_DEMOS, seed=1000 + world)
    n = terrain.mdp.n_states
    return Problem(
        states=n,
        world=world,
        side=size,
        tasks=[TaskData(terrain.mdp, s.trajectories, s.name) for s in sims],
        true_rewards=[s.true_reward for s in sims],
        scored=[np.arange(n) != s.goal for s in sims],
    )


def motion_problem() -> Problem:
    """scale.py's 80,000-state velocity-grid tasks, with the true reward `motion_tasks` demonstrated."""
    from benchmarks.scale import SIZE, motion_goal, motion_reward, motion_tasks

    tasks = motion_tasks(N_TASKS, n_demos=N_DEMOS, seed=0)
    rewards, scored = [], []
    for task in tasks:
        goal_cell = motion_goal(task)
        keep = np.ones(task.mdp.n_states, dtype=bool)
        keep[goal_cell :: SIZE * SIZE] = False  # the goal cell's 8 direction states
        rewards.append(motion_reward(goal_cell, seed=0))
        scored.append(keep)
    return Problem(
        states=tasks[0].mdp.n_states, world=0, side=SIZE, tasks=tasks, true_rewards=rewards, scored=scored
    )


def problems(size: int, worlds: int) -> list[Problem]:
    """The worlds of one size class (80,000 states: the single motion MDP)."""
    if size == 80000:
        return [motion_problem()]
    side = 32 if size == 1000 else 100
    return [terrain_problem(side, w) for w in range(worlds)]


def scores(problem: Problem, rewards: np.ndarray) -> list[float]:
    """Pearson correlation of each learned task reward with its true reward on the scored states."""
    from metairl_engine.metrics import pearson

    return [
        pearson(r, t, mask=m) for r, t, m in zip(rewards, problem.true_rewards, problem.scored, strict=True)
    ]


def run_engine(problem: Problem, config: FitConfig) -> dict[str, Any]:
    """One fit of all the problem's tasks with ``config``: time per task and the tasks' correlations."""
    from metairl_engine.fit import fit

    started, cpu_started = time.perf_counter(), time.process_time()
    result = fit(problem.tasks, config)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu_started
    n = len(problem.tasks)
    return {
        "seconds_per_task": wall / n,
        "cpu_seconds_per_task": cpu / n,
        "pearson": scores(problem, result.rewards),
        "steps": len(result.history),
        "kept_step": result.best_step,
    }


def dense_gb(problem: Problem) -> float:
    """GB of imitation's dense float64 (S, A, S) transition matrix for this problem."""
    mdp = problem.tasks[0].mdp
    return mdp.n_states * mdp.n_actions * mdp.n_states * 8 / 1e9


def padded_demos(problem: Problem, horizon: int) -> np.ndarray:
    """(tasks, demos, horizon + 1) visited states, each demonstration cut at or held at its last state to the horizon."""
    out = np.empty((len(problem.tasks), N_DEMOS, horizon + 1), dtype=np.int64)
    for i, task in enumerate(problem.tasks):
        for j, tr in enumerate(task.trajectories):
            states = tr.states[: horizon + 1]
            out[i, j, : len(states)] = states
            out[i, j, len(states) :] = states[-1]
    return out


def run_imitation(problem: Problem, python: Path, iterations: int) -> dict[str, Any]:
    """Fit each task with imitation's MCE IRL in a subprocess of ``python``, exchanging .npz files."""
    mdp = problem.tasks[0].mdp
    assert mdp.next_state is not None and mdp.features is not None
    horizon = HORIZON_PER_SIDE * problem.side
    with tempfile.TemporaryDirectory() as tmp:
        given, back = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(
            given,
            next_state=mdp.next_state,
            features=mdp.features,
            demo_states=padded_demos(problem, horizon),
            gamma=mdp.gamma,
            iterations=iterations,
        )
        subprocess.run(
            [str(python), __file__, "--imitation-worker", str(given), str(back)],
            check=True,
            env={**os.environ, **THREAD_ENV},
        )
        with np.load(back) as out:
            rewards, wall, cpu = out["rewards"], float(out["seconds"]), float(out["cpu_seconds"])
            linf, versions = out["linf"], str(out["versions"])
    n = len(problem.tasks)
    return {
        "seconds_per_task": wall / n,
        "cpu_seconds_per_task": cpu / n,
        "pearson": scores(problem, rewards),
        "horizon": horizon,
        "iterations": iterations,
        "seconds_per_iteration": wall / n / iterations,
        "linf_gap": float(linf.mean()),
        "versions": versions,
    }


def imitation_worker(given: Path, back: Path) -> None:
    """Run imitation's MCE IRL on every task of ``given`` (.npz) and write rewards and seconds to ``back``.

    Runs in the imitation venv: it imports imitation, seals and torch, never this engine.
    """
    import imitation
    import torch
    from imitation.algorithms import mce_irl
    from imitation.rewards import reward_nets
    from imitation.util import logger
    from seals import base_envs

    torch.set_num_threads(1)
    with np.load(given) as data:
        next_state, features, demos = data["next_state"], data["features"], data["demo_states"]
        gamma, iterations = float(data["gamma"]), int(data["iterations"])
    n_states, n_actions = next_state.shape
    horizon = demos.shape[2] - 1
    started, cpu_started = time.perf_counter(), time.process_time()
    transitions = np.zeros((n_states, n_actions, n_states))
    transitions[np.arange(n_states)[:, None], np.arange(n_actions)[None, :], next_state] = 1.0
    discounts = gamma ** np.arange(horizon + 1)
    rewards, linf = [], []
    with tempfile.TemporaryDirectory() as log_dir:
        for task_demos in demos:
            start = np.bincount(task_demos[:, 0], minlength=n_states) / len(task_demos)
            env = base_envs.TabularModelPOMDP(
                transition_matrix=transitions,
                observation_matrix=features,
                reward_matrix=np.zeros(n_states),
                horizon=horizon,
                initial_state_dist=start,
            )
            # imitation's discounted occupancy of trajectories (MCEIRL._set_demo_from_trajectories)
            occupancy = np.zeros(n_states)
            for states in task_demos:
                np.add.at(occupancy, states, discounts)
            torch.manual_seed(0)
            net = reward_nets.BasicRewardNet(
                env.observation_space, env.action_space, use_action=False, hid_sizes=MCE_HIDDEN
            )
            irl = mce_irl.MCEIRL(
                occupancy / len(task_demos),
                env,
                net,
                rng=np.random.default_rng(0),
                optimizer_kwargs={"lr": MCE_LEARNING_RATE},
                discount=gamma,
                log_interval=None,
                custom_logger=logger.configure(log_dir, format_strs=[]),
            )
            visits = irl.train(max_iter=iterations)
            linf.append(float(np.max(np.abs(visits - irl.demo_state_om))))
            with torch.no_grad():
                rewards.append(net(torch.as_tensor(features), None, None, None).numpy())
    np.savez(
        back,
        rewards=np.asarray(rewards, dtype=np.float32),
        seconds=time.perf_counter() - started,
        cpu_seconds=time.process_time() - cpu_started,
        linf=np.asarray(linf),
        versions=f"imitation {imitation.__version__}, torch {torch.__version__}",
    )


def measure(size: int, args: argparse.Namespace) -> list[dict[str, Any]]:
    """All rows of one size class: per world and method a measurement, or a row saying why it did not run."""
    from metairl_engine import FitConfig

    small = size == 1000
    methods: list[tuple[str, FitConfig]] = [("engine default", FitConfig())]
    if small:
        methods += [(capped(n), FitConfig(max_steps=n)) for n in args.capped_steps]
    if small or args.maxent_large:
        methods.append(("engine maxent", FitConfig(method="maxent")))
    rows = []
    for problem in problems(size, args.worlds if small else 1):
        base = {"size": size, "states": problem.states, "world": problem.world, "tasks": len(problem.tasks)}
        for method, config in methods:
            out = run_engine(problem, config)
            rows.append({**base, "method": method, **out, "load_average": os.getloadavg()[0]})
            print(f"{size} world {problem.world} {method}: {rows[-1]}", file=sys.stderr, flush=True)
        gb = dense_gb(problem)
        if gb > args.max_dense_gb:
            note = f"not run: needs {gb:.1f} GB dense transitions (limit {args.max_dense_gb:g} GB)"
            rows.append({**base, "method": IMITATION, "not_run": note})
        elif not args.imitation_python.exists():
            note = f"not run: no imitation python at {args.imitation_python.name} (see the docstring)"
            rows.append({**base, "method": IMITATION, "not_run": note})
        else:
            out = run_imitation(problem, args.imitation_python, args.imitation_iterations)
            rows.append({**base, "method": IMITATION, **out, "load_average": os.getloadavg()[0]})
        print(f"{size} world {problem.world} imitation: {rows[-1]}", file=sys.stderr, flush=True)
    return rows


def notes(method: str, ran: list[dict[str, Any]]) -> str:
    """The table's notes for one size and method: steps or iterations per world, imitation's settings."""
    if method.startswith("engine default"):
        return "steps (kept) per world: " + ", ".join(f"{r['steps']} ({r['kept_step']})" for r in ran)
    if method == "engine maxent":
        return "L-BFGS iterations per world (all tasks): " + ", ".join(str(r["steps"]) for r in ran)
    first = ran[0]
    per_iteration = np.mean([r["seconds_per_iteration"] for r in ran])
    gap = np.mean([r["linf_gap"] for r in ran])
    return (
        f"horizon {first['horizon']}, {first['iterations']} Adam iterations ({per_iteration:.2f} s each), "
        f"final L∞ occupancy gap {gap:.2f}; {first['versions']}"
    )


def table(rows: list[dict[str, Any]]) -> str:
    """Markdown table over worlds and tasks per size and method, then the engine's speed-up over imitation."""
    lines = [
        "| states | method | tasks | time per task (s), wall (CPU) | Pearson, goal excluded | notes |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    speedups = []
    for size, label in SIZES.items():
        per_task: dict[str, tuple[float, float]] = {}
        for method in dict.fromkeys(r["method"] for r in rows if r["size"] == size):  # in order of first row
            sel = [r for r in rows if r["size"] == size and r["method"] == method]
            ran = [r for r in sel if "pearson" in r]
            if not sel:
                continue
            if not ran:
                lines.append(f"| {label} | {method} | – | – | – | {sel[0]['not_run']} |")
                continue
            tasks = sum(r["tasks"] for r in ran)
            wall = float(np.mean([r["seconds_per_task"] for r in ran]))
            cpu = float(np.mean([r["cpu_seconds_per_task"] for r in ran]))
            rho = np.concatenate([r["pearson"] for r in ran])
            per_task[method] = (wall, cpu)
            lines.append(
                f"| {label} | {method} | {tasks} | {wall:.2f} ({cpu:.2f}) | {rho.mean():.3f} ± {rho.std():.3f} "
                f"| {notes(method, ran)} |"
            )
        if IMITATION in per_task:
            (iw, ic) = per_task[IMITATION]
            for method, (w, c) in per_task.items():
                if method != IMITATION:
                    speedups.append(f"- {label}: {method} vs imitation: {iw / w:.1f}× (CPU {ic / c:.1f}×)")
    if speedups:
        lines += ["", "Speed-up in time per task (imitation's time / this engine's time; target ≥ 50×):"]
        lines += speedups
    return "\n".join(lines)


def main() -> None:
    """Parse arguments; run the imitation worker, or the measurements then the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=list(SIZES), choices=list(SIZES))
    parser.add_argument(
        "--worlds", type=int, default=3, help="worlds at 1,024 states (1 at the larger sizes)"
    )
    parser.add_argument(
        "--capped-steps",
        type=int,
        nargs="*",
        default=[],
        help="at 1,024 states also fit with max_steps capped at each N (how soon the engine passes imitation)",
    )
    parser.add_argument("--maxent-large", action="store_true", help="run maxent at 10,000 and 80,000 too")
    parser.add_argument("--imitation-python", type=Path, default=ROOT / ".venv-imitation/bin/python")
    parser.add_argument("--imitation-iterations", type=int, default=50)
    parser.add_argument("--max-dense-gb", type=float, default=4.0)
    parser.add_argument("--results", type=Path, default=HERE / "versus_results.json")
    parser.add_argument("--imitation-worker", nargs=2, type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.imitation_worker:
        imitation_worker(*args.imitation_worker)
        return

    import torch

    torch.set_num_threads(1)
    if not args.imitation_python.exists():
        print(f"note: no imitation python at {args.imitation_python}: its column is skipped", flush=True)
    from benchmarks.provenance import provenance

    run = provenance()
    rows = [{**r, "provenance": run} for size in args.sizes for r in measure(size, args)]
    kept = json.loads(args.results.read_text()) if args.results.exists() else []
    rows = [r for r in kept if r["size"] not in args.sizes] + rows
    args.results.write_text(json.dumps(rows, indent=1) + "\n")
    print(table(rows))


if __name__ == "__main__":
    main()
