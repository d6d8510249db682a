"""Stopping rule check: where does the held-out rule stop, against the step a known reward prefers?

Runs the fit's own loop (`metairl_engine.fit` internals, one member, default config otherwise) for a fixed
number of steps on problems with a known reward, and every ``--every`` steps scores the live networks'
task rewards against the truth (Pearson, goal excluded). Reports, per problem: the step of the lowest
held-out NLL, the steps the stopping rules keep (the one-standard-error rule on the mean, and the same
rule on the paired differences with the best step, the same on the calibrated NLL, and where the engine's
own rule stops and what it keeps), and the accuracy at each, beside the best accuracy
any step reached. Problems: terrain worlds of both generators, and terrain on the velocity grid (the
motion model: state = (cell, direction), true reward = −cost of the cell + goal bonus). Usage::

    python -m benchmarks.stopping --worlds 3 --steps 600
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from benchmarks.accuracy import world_and_tasks
from benchmarks.frozen_terrain import frozen_world_and_tasks
from metairl_engine import FitConfig
from metairl_engine.fit import HeldOutStopper, _evaluate, _Problem, gradient_step
from metairl_engine.grids import grid_mdp
from metairl_engine.metrics import pearson
from metairl_engine.networks import StackedMLP
from metairl_engine.results import TaskData
from metairl_engine.sim.terrain import SimTask, World, make_tasks, make_world

HERE = Path(__file__).resolve().parent


def velocity_world_and_tasks(index: int) -> tuple[World, list[SimTask]]:
    """A 12×12 velocity grid (1,152 states) whose cell costs are a repo-generator terrain, 8 goal tasks."""
    cells = make_world(size=12, n_hills=4, seed=900 + index)
    mdp = grid_mdp(width=12, height=12, velocity=True, gamma=0.9)
    world = World(size=12, cost=np.tile(cells.cost, 8), mdp=mdp)
    return world, make_tasks(world, n_tasks=8, n_demos=3, seed=9_000 + index)


GENERATORS = {"repo": world_and_tasks, "frozen": frozen_world_and_tasks, "velocity": velocity_world_and_tasks}


@dataclass
class Trace:
    """Per step: held-out NLL of each held-out step (rows) and, every few steps, the mean task accuracy."""

    held: list[np.ndarray]
    calibrated: list[np.ndarray]
    accuracy: dict[int, float]


def trace(world: World, sims: list[SimTask], *, steps: int, every: int, config: FitConfig) -> Trace:
    """Run ``steps`` Adam steps of the fit's loop, recording held-out NLLs and accuracy of the live nets."""
    chosen = sims[:8]
    tasks = [TaskData(world.mdp, s.trajectories[:3], s.name) for s in chosen]
    problem = _Problem(tasks, config)
    generator = torch.Generator().manual_seed(config.seed)
    n_inputs = problem.features.shape[1] if problem.features is not None else problem.n_states
    vr = StackedMLP(
        n_members=problem.n_nets, n_inputs=n_inputs, hidden=config.hidden, tabular=False, generator=generator
    )
    base = StackedMLP(
        n_members=1, n_inputs=n_inputs, hidden=config.hidden, tabular=False, generator=generator
    )
    optimiser = torch.optim.Adam([*vr.parameters(), *base.parameters()], lr=config.learning_rate)
    masks = [np.arange(world.mdp.n_states) != s.goal for s in chosen]
    out = Trace(held=[], calibrated=[], accuracy={})
    temperatures = torch.logspace(-2, 2, 17, base=2.0)
    for step in range(1, steps + 1):
        optimiser.zero_grad(set_to_none=True)
        block = (step - 1) % len(problem.blocks)
        *_, f = gradient_step(problem, vr, base, config, block=block)
        with torch.no_grad():
            q = problem.blocks[block].q_held(f)
            per_step = F.cross_entropy(q, problem.held_actions, reduction="none")
            scaled = torch.stack(
                [F.cross_entropy(t * q, problem.held_actions, reduction="none") for t in temperatures]
            )
            calibrated = scaled[scaled.mean(dim=1).argmin()]
        out.held.append(per_step.numpy().copy())
        out.calibrated.append(calibrated.numpy().copy())
        if step % every == 0 or step == 1:
            result, _ = _evaluate(problem, vr, base, config, history=[], best_step=step)
            out.accuracy[step] = float(
                np.mean(
                    [
                        pearson(result.rewards[i], s.true_reward, mask=m)
                        for i, (s, m) in enumerate(zip(chosen, masks, strict=True))
                    ]
                )
            )
        optimiser.step()
    return out


def kept_step(held: list[np.ndarray], *, paired: bool) -> int:
    """The last step within one standard error of the best so far (as fit.HeldOutStopper keeps)."""
    best, best_rows, tol, kept = np.inf, held[0], 0.0, 1
    for step, rows in enumerate(held, start=1):
        mean = float(rows.mean())
        if mean < best:
            best, best_rows = mean, rows
            tol = float(rows.std()) / np.sqrt(rows.size)
        if paired:
            diff = rows - best_rows
            tol = float(diff.std()) / np.sqrt(rows.size)
            within = diff.mean() <= tol
        else:
            within = mean <= best + tol
        if within:
            kept = step
    return kept


def engine_rule(calibrated: list[np.ndarray], *, patience: int) -> tuple[int, int]:
    """(step the fit stops at, step it keeps) under the engine's own rule (fit.HeldOutStopper)."""
    stopper = HeldOutStopper(patience=patience)
    for step, rows in enumerate(calibrated, start=1):
        stopper.update(step, torch.from_numpy(rows))
        if stopper.should_stop(step):
            return step, stopper.kept_step
    return len(calibrated), stopper.kept_step


def nearest(accuracy: dict[int, float], step: int) -> float:
    """Accuracy at the recorded step nearest to ``step``."""
    return accuracy[min(accuracy, key=lambda s: abs(s - step))]


def main() -> None:
    """Trace every problem and print one table row per (generator, world)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, default=3)
    parser.add_argument("--steps", type=int, default=600)
    parser.add_argument("--every", type=int, default=10)
    parser.add_argument("--generators", nargs="*", default=list(GENERATORS), choices=list(GENERATORS))
    parser.add_argument(
        "--patience", type=int, nargs="*", default=[FitConfig().patience], help="the engine's rule, per value"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    config = replace(FitConfig(), ensemble=1)
    print(
        "| problem | min held-out NLL: step (acc) | one-SE rule: step (acc) | paired rule: step (acc) "
        "| calibrated one-SE: step (acc) | "
        + " | ".join(f"engine's rule, patience {p}: stop, kept (acc)" for p in args.patience)
        + " | best accuracy: step (acc) | last step acc |"
    )
    print("| --- " * (7 + len(args.patience)) + "|")
    for g in args.generators:
        for w in range(args.worlds):
            world, sims = GENERATORS[g](w)
            t = trace(world, sims, steps=args.steps, every=args.every, config=config)
            nll = np.array([h.mean() for h in t.held])
            best_nll = int(nll.argmin()) + 1
            one_se, paired = kept_step(t.held, paired=False), kept_step(t.held, paired=True)
            calibrated = kept_step(t.calibrated, paired=False)
            rules = [engine_rule(t.calibrated, patience=p) for p in args.patience]
            best_acc = max(t.accuracy, key=lambda s: t.accuracy[s])
            print(
                f"| {g} world {w} | {best_nll} ({nearest(t.accuracy, best_nll):.3f}) "
                f"| {one_se} ({nearest(t.accuracy, one_se):.3f}) | {paired} ({nearest(t.accuracy, paired):.3f}) "
                f"| {calibrated} ({nearest(t.accuracy, calibrated):.3f}) "
                + "".join(f"| {stop}, {kept} ({nearest(t.accuracy, kept):.3f}) " for stop, kept in rules)
                + f"| {best_acc} ({t.accuracy[best_acc]:.3f}) | {t.accuracy[max(t.accuracy)]:.3f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
