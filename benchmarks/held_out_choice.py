"""Would the held-out-demonstration choice help where the features say more than the place?

`FitConfig.tabular_choice` fits the networks and the tabular `maxent` solver on folds of the demonstrations
and keeps `shared_maxent` where the solver predicts the held-out demonstrations better; it is made only on MDPs
without features or whose features only say where a state is (`fit.tabular_choice_applies`). This probe makes
it on a family's worlds as they are, features and all, with the default config: per world, the held-out NLL
of both (`holdout.demonstration_folds`, every demonstration held out once), raw and with one temperature per
model fitted to the held-out steps,

    NLL(β) = −Σ_t [β log π(a_t|s_t) − log Σ_a π(a|s_t)^β],   β* = argmin_β NLL(β)   (convex in β),

so the confidence (b and the reward's scale are one parameter) is not what is judged; the choice each would
make; and the scores (Pearson, goal excluded; EVD÷random) of the networks (the default's cached row of
`benchmarks/families_results.json`) and of `shared_maxent` on every demonstration. Usage::

    .venv/bin/python -m benchmarks.held_out_choice objectworld 16 0 1
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from typing import Any

import numpy as np
import torch
from scipy.optimize import minimize_scalar

from benchmarks.families import CACHE, FAMILIES, config_of, key_of, run_one, tasks_of
from metairl_engine.demos import Trajectory, state_action_pairs
from metairl_engine.fit import fit, task_stays
from metairl_engine.holdout import demonstration_folds
from metairl_engine.maxent import fit_maxent
from metairl_engine.results import TaskData

MAX_TEMPERATURE = 20.0
"""The largest β searched: a policy sharpened further is as good as deterministic."""


def held_out_steps(policies: np.ndarray, held: list[list[Trajectory]]) -> tuple[np.ndarray, np.ndarray]:
    """log π(·|s) (N, A) at every held-out step of every task, float64, and the actions taken (N,)."""
    logs, actions = [], []
    for policy, trajectories in zip(policies, held, strict=True):
        states, taken = state_action_pairs(trajectories)
        logs.append(np.log(np.maximum(policy[states].astype(np.float64), 1e-12)))
        actions.append(taken)
    return np.concatenate(logs), np.concatenate(actions)


def tempered_nll(log_policy: np.ndarray, actions: np.ndarray, beta: float) -> float:
    """NLL(β) of the actions under π^β renormalised per state (β = 1: the policy as it is)."""
    scaled = beta * log_policy
    peak = scaled.max(axis=1, keepdims=True)
    log_norm = peak[:, 0] + np.log(np.exp(scaled - peak).sum(axis=1))
    return float((log_norm - scaled[np.arange(len(actions)), actions]).sum())


def calibrated_nll(log_policy: np.ndarray, actions: np.ndarray) -> tuple[float, float]:
    """(min over β of `tempered_nll`, the β that reaches it)."""
    found = minimize_scalar(
        lambda b: tempered_nll(log_policy, actions, b), bounds=(1e-3, MAX_TEMPERATURE), method="bounded"
    )
    return float(found.fun), float(found.x)


def probe_world(family: str, n_demos: int, index: int) -> dict[str, Any]:
    """One world: both models' held-out NLL (raw, calibrated), the choices, and both models' scores."""
    spec = FAMILIES[family]
    world = spec.world(index)
    sims = tasks_of(spec, world, index, n_demos)
    config = config_of("default")
    tasks = [TaskData(world.mdp, s.trajectories, s.name) for s in sims]
    folds = demonstration_folds(
        [t.trajectories for t in tasks], stays=task_stays(tasks) if config.stay_at_ends else None
    )
    steps: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"networks": [], "solver": []}
    for train, held in folds:
        trained = [replace(t, trajectories=demos) for t, demos in zip(tasks, train, strict=True)]
        networks = fit(trained, replace(config, tabular_choice=False))
        solver = fit_maxent(trained, replace(config, method="maxent"))
        steps["networks"].append(held_out_steps(networks.policies, held))
        steps["solver"].append(held_out_steps(solver.policies, held))
    row: dict[str, Any] = {"family": family, "demos": n_demos, "world": index}
    for model, parts in steps.items():
        log_policy, actions = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        calibrated, beta = calibrated_nll(log_policy, actions)
        row[model] = {"raw": tempered_nll(log_policy, actions, 1.0), "calibrated": calibrated, "beta": beta}
    row["steps"] = len(actions)
    for way in ("raw", "calibrated"):
        row[f"{way}_choice"] = "solver" if row["solver"][way] < row["networks"][way] else "networks"
    cached = [
        r
        for r in json.loads(CACHE.read_text())
        if (r["family"], r["demos"], r["world"], r["key"]) == (family, n_demos, index, key_of("default"))
    ]
    shared = run_one(world, sims, replace(config, method="shared_maxent"))
    for name, scored in (
        ("networks_scores", cached[0] if cached else None),
        ("shared_maxent_scores", shared),
    ):
        row[name] = None if scored is None else {k: scored[k] for k in ("pearson", "evd_random")}
    return row


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("family", choices=sorted(FAMILIES))
    parser.add_argument("demos", type=int)
    parser.add_argument("worlds", type=int, nargs="+")
    args = parser.parse_args()
    torch.set_num_threads(1)  # as `benchmarks.families` fits
    for index in args.worlds:
        print(json.dumps(probe_world(args.family, args.demos, index)), flush=True)


if __name__ == "__main__":
    main()
