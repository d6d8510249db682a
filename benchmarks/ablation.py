"""Ablation: each candidate change to the default config, measured one by one on every terrain generator.

The setting: 8 tasks × 3 demonstrations, goal state excluded, 10 worlds of the repo's generator
(`metairl_engine/sim/terrain.py`, tuned on), of the frozen one (`frozen_terrain.py`, never tuned on) and of
``slip``: the repo's worlds with stochastic moves (`slippery_world_and_tasks`, never tuned on). A variant is a
named set of FitConfig overrides; every fit is cached in `ablation_results.json` with the engine it ran on
and its provenance, so a rerun only computes what is missing. Usage::

    python -m benchmarks.ablation                      # every variant, every generator
    python -m benchmarks.ablation --variants default none
    python -m benchmarks.ablation --featureless --variants default one-hot none   # tabular uploads
    python -m benchmarks.ablation --table               # print the table from the cache only
    python -m benchmarks.ablation --table --choose --variants w0.3 default w3   # choice by held-out NLL
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from benchmarks.accuracy import ENGINE, run_one, world_and_tasks
from benchmarks.frozen_terrain import frozen_world_and_tasks
from benchmarks.provenance import provenance
from metairl_engine import FitConfig
from metairl_engine.grids import grid_mdp
from metairl_engine.sim.terrain import SimTask, World, make_tasks, make_world

HERE = Path(__file__).resolve().parent

SLIP = 0.2
"""The ``slip`` generator's probability that a step goes where another move (uniformly chosen) leads."""


def slippery_world_and_tasks(index: int) -> tuple[World, list[SimTask]]:
    """The repo's world ``index`` with stochastic moves (slip SLIP): its tasks' demonstrator plans for the
    slips and its demonstrations contain them; never tuned on (dynamics unlike either generator's)."""
    world = make_world(size=16, n_hills=6, seed=index)
    world = replace(
        world, mdp=grid_mdp(width=16, height=16, moves=8, stay=True, gamma=world.mdp.gamma, slip=SLIP)
    )
    return world, make_tasks(world, n_tasks=16, n_demos=10, seed=1000 + index)


GENERATORS: dict[str, Callable[[int], tuple[World, list[SimTask]]]] = {
    "repo": world_and_tasks,
    "frozen": frozen_world_and_tasks,
    "slip": slippery_world_and_tasks,
}

VARIANTS: dict[str, dict[str, Any]] = {
    # The paper's config: Huber sharing, weight 1, one network per task, one seed.
    "paper-huber": {"sharing": "huber"},
    "none": {"sharing": "none"},
    "l2": {"sharing": "l2"},
    "std": {"sharing": "std"},
    "huber-ens1": {"sharing": "huber", "ensemble": 1},
    "huber-ens2": {"sharing": "huber", "ensemble": 2},
    "huber-ens3": {"sharing": "huber", "ensemble": 3},
    "huber-ens4": {"sharing": "huber", "ensemble": 4},
    "l2-ens4": {"sharing": "l2", "ensemble": 4},
    "none-ens4": {"sharing": "none", "ensemble": 4},
    "huber-fourier3": {"sharing": "huber", "fourier_octaves": 3},
    "huber-fourier2": {"sharing": "huber", "fourier_octaves": 2},
    "huber-ens4-narrow": {"sharing": "huber", "ensemble": 4, "hidden": (64, 32, 16)},
    "huber-narrow": {"sharing": "huber", "hidden": (64, 32, 16)},
    "default": {},
    # Cheaper fits: fewer steps, narrower networks, a larger step size.
    "ens4-steps300": {"ensemble": 4, "max_steps": 300},
    "ens4-steps500": {"ensemble": 4, "max_steps": 500},
    "ens4-narrow-steps500": {"ensemble": 4, "hidden": (64, 32, 16), "max_steps": 500},
    "ens4-narrow-lr02-steps500": {
        "ensemble": 4,
        "hidden": (64, 32, 16),
        "learning_rate": 0.02,
        "max_steps": 500,
    },
    "ens4-lr02-steps300": {"ensemble": 4, "learning_rate": 0.02, "max_steps": 300},
    "patience100": {"patience": 100},
    "patience300": {"patience": 300},
    "lr02": {"learning_rate": 0.02},
    "visited": {"sharing_states": "visited"},
    # Sharing blocks (automatic only from 32,768 states): forced on these small worlds to check that the
    # block estimate of the sharing loss costs no accuracy.
    "blocks4": {"sharing_blocks": 4},
    # The sharing weight, for choosing it per demonstrator by held-out likelihood (`heldout_nll` of each row).
    "w0.3": {"sharing_weight": 0.3},
    "w3": {"sharing_weight": 3.0},
    "one-hot": {"tabular_inputs": "one_hot"},
    # The baseline learning from every task's reward alike on every state, as the paper has it.
    "elsewhere1": {"baseline_elsewhere_weight": 1.0},
    # without features: the networks on coordinates alone, never the tabular solver
    "networks-only": {"tabular_choice": False},
}
"""Named FitConfig overrides; ``default`` is whatever FitConfig() is at the time of the run."""


NO_FEATURES = " (no features)"
"""Label suffix of fits whose MDP was given without features or layout (``--featureless``)."""


def without_features(world: World) -> World:
    """The world with an MDP of the same transitions but no features and no layout: a tabular upload."""
    return replace(world, mdp=replace(world.mdp, features=None, layout=None))


def config_of(variant: str) -> FitConfig:
    """The FitConfig a variant names (today's defaults plus its overrides)."""
    return replace(FitConfig(), **VARIANTS[variant])


def key_of(variant: str) -> str:
    """Cache key of a variant: the engine it runs on and its full config, so no stale row is ever reused."""
    return f"{ENGINE}:" + json.dumps(config_of(variant).to_dict(), sort_keys=True)


def table(rows: list[dict[str, Any]], labels: list[str]) -> str:
    """Markdown: per label, task-reward Pearson (goal excluded) mean ± std over worlds on each generator."""
    names = " / ".join(GENERATORS)
    lines = [
        "| variant | "
        + " | ".join(f"{g} generator" for g in GENERATORS)
        + f" | baseline vs −cost ({names}) | CPU s/fit ({names}) |",
        "| --- " * (len(GENERATORS) + 3) + "|",
    ]
    for v in labels:
        cells, base, secs = [], [], []
        for g in GENERATORS:
            sel = [r for r in rows if r["variant"] == v and r["generator"] == g]
            if not sel:
                cells.append("—")
                base.append("—")
                secs.append("—")
                continue
            tp = np.array([r["task_pearson"] for r in sel])
            cells.append(f"{tp.mean():.3f} ± {tp.std():.3f} (n={len(sel)})")
            base.append(f"{np.mean([r['baseline_pearson'] for r in sel]):.3f}")
            secs.append(f"{np.mean([r.get('cpu_seconds', r['seconds']) for r in sel]):.1f}")
        lines.append(f"| {v} | {' | '.join(cells)} | {' / '.join(base)} | {' / '.join(secs)} |")
    return "\n".join(lines)


def heldout_choice(rows: list[dict[str, Any]], labels: list[str]) -> str:
    """Markdown: per generator, the accuracy of picking, per world, the label whose fit has the lowest held-out
    NLL at its kept step (what a user could do without the true reward) against each label alone."""
    lines = [
        "| generator | " + " | ".join(labels) + " | chosen by held-out NLL | best per world (true reward) |"
    ]
    lines.append("| --- " * (len(labels) + 3) + "|")
    for g in GENERATORS:
        by_world: dict[int, dict[str, dict[str, Any]]] = {}
        for r in rows:
            if r["generator"] == g and r["variant"] in labels and not np.isnan(r.get("heldout_nll", np.nan)):
                by_world.setdefault(r["world"], {})[r["variant"]] = r
        complete = [fits for fits in by_world.values() if len(fits) == len(labels)]
        if not complete:
            continue
        alone = [np.mean([fits[v]["task_pearson"] for fits in complete]) for v in labels]
        chosen = [min(fits.values(), key=lambda r: r["heldout_nll"]) for fits in complete]
        best = np.mean([max(r["task_pearson"] for r in fits.values()) for fits in complete])
        picks = ", ".join(f"{v} {sum(c['variant'] == v for c in chosen)}×" for v in labels)
        lines.append(
            f"| {g} ({len(complete)} worlds) | "
            + " | ".join(f"{a:.3f}" for a in alone)
            + f" | {np.mean([c['task_pearson'] for c in chosen]):.3f} ({picks}) | {best:.3f} |"
        )
    return "\n".join(lines)


def main() -> None:
    """Run what is missing from the cache, then print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--generators", nargs="*", default=list(GENERATORS), choices=list(GENERATORS))
    parser.add_argument("--worlds", type=int, default=10)
    parser.add_argument("--tasks", type=int, default=8)
    parser.add_argument("--demos", type=int, default=3)
    parser.add_argument("--table", action="store_true", help="only print the table from the cache")
    parser.add_argument(
        "--all", action="store_true", help="table of every label in the cache, other engines' too"
    )
    parser.add_argument("--cache", type=Path, default=HERE / "ablation_results.json")
    parser.add_argument(
        "--choose", action="store_true", help="also: the variants chosen per world by held-out NLL"
    )
    parser.add_argument(
        "--featureless",
        action="store_true",
        help="fit each world's MDP without its features and layout (labels get NO_FEATURES)",
    )
    args = parser.parse_args()

    import torch

    torch.set_num_threads(1)
    rows: list[dict[str, Any]] = json.loads(args.cache.read_text()) if args.cache.exists() else []
    setting = {"tasks": args.tasks, "demos": args.demos}
    done = {
        (r["generator"], r["config_key"], r["world"])
        for r in rows
        if r["tasks"] == args.tasks and r["demos"] == args.demos
    }
    suffix = NO_FEATURES if args.featureless else ""
    run = provenance()
    todo = [
        (g, v, w)
        for v in args.variants
        for g in args.generators
        for w in range(args.worlds)
        if (g, key_of(v) + suffix, w) not in done and not args.table
    ]
    worlds: dict[tuple[str, int], tuple[World, list[SimTask]]] = {}
    for g, v, w in tqdm(todo, desc="fits"):
        if (g, w) not in worlds:
            world, sims = GENERATORS[g](w)
            worlds[g, w] = (without_features(world) if args.featureless else world), sims
        world, sims = worlds[g, w]
        out = run_one(world, sims, n_tasks=args.tasks, n_demos=args.demos, config=config_of(v))
        key = key_of(v) + suffix
        rows.append(
            {
                "generator": g,
                "variant": v + suffix,
                "config_key": key,
                "world": w,
                **setting,
                **out,
                "provenance": run,
            }
        )
        args.cache.write_text(json.dumps(rows, indent=0))
    current = {key_of(v) + suffix for v in args.variants}
    wanted = [
        r
        for r in rows
        if r["tasks"] == args.tasks
        and r["demos"] == args.demos
        and r["world"] < args.worlds
        and (args.all or r["config_key"] in current)
    ]
    labels = list(dict.fromkeys(r["variant"] for r in wanted))
    print(f"{args.tasks} tasks × {args.demos} demonstrations, {args.worlds} worlds, goal state excluded")
    print(table(wanted, labels))
    if args.choose:
        print()
        print(heldout_choice(wanted, labels))


if __name__ == "__main__":
    main()
