"""The paper's Table I on the synthetic patient, through the engine directly (no service).

For each session (unstimulated, stimulated) of `metairl_engine.sim.patient.simulate_patient`, the COP recording is
cut into per-direction demonstrations (`metairl_engine.motion.recording.demonstrations`) and one meta-IRL fit with Huber
sharing and the default config learns a reward per instructed direction plus the baseline on the velocity
grid (100×100 = 80,000 states by default). The table gives the Pearson correlation of every recovered task
reward with the patient's ideal reward, and of the baseline with it (the paper's "origin" column), on the
states the demonstrations visit and on all states, with the wall time of each session's fit. Usage::

    python -m benchmarks.motion [--size 100] [--seed 0] [--out benchmarks/MOTION.md]
        [--images benchmarks/motion] [--outward-only] [--direction-preference R R R R R R R R]

``--size 30`` (7,200 states) runs in a few minutes for a quick look; only 100 reproduces the paper's MDP.

The identifiability study (docs/motion.md) is a subcommand: it fits both sessions of the planning patient and
of the controller patient (`metairl_engine.sim.controller_patient`) with each config of `VARIANTS` and scores the
learned baseline against the inherent preference; rows accumulate in ``benchmarks/motion/identifiability.json``
and the table, with the kinematic readout of the same recordings, replaces MOTION.md's identifiability block::

    python -m benchmarks.motion identify [--size 30] [--seed 0]
        [--generators planner controller controller-null] [--variants NAME ...] [--only-table]

Whether the motion summary's verdict on the learned readout is right (docs/motion.md, "Does the learned
readout agree with the recordings"), on the planner and on controllers weak left, right and forward left::

    .venv/bin/python -m benchmarks.motion agreement [--size 30] [--seed 0] [--patients NAME ...]

How well the model-free `path_bend` readout and the peak reach rank each patient's true preference, over
seeds, with no fit (docs/motion.md, "Path bend")::

    .venv/bin/python -m benchmarks.motion bend [--size 30] [--seeds 5]

Seventeen readings of the agreement fits of the tuning controllers (`benchmarks.motion_readings`), each scored
against the true preference, with the weak-left controller whose paths ignore its preference beside
(docs/motion.md, "Why no reading of the fit ranks a controller's preference")::

    .venv/bin/python -m benchmarks.motion readings [--size 30] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import torch
from scipy.stats import spearmanr

from benchmarks.motion_readings import (
    COMPARISON,
    READINGS,
    Reading,
    SessionFit,
    demonstrated_drift,
    offsets,
    policy_drift,
    score,
    spearman,
)
from metairl_engine import FitConfig, Layout, Trajectory
from metairl_engine.fit import FitResult, Progress, TaskData, fit
from metairl_engine.grids import DIRECTION_NAMES, grid_mdp, velocity_coords
from metairl_engine.metrics import pearson
from metairl_engine.motion.kinematics import compare_recordings, comparison_png, movements
from metairl_engine.motion.readout import (
    agreement,
    direction_readout,
    path_bend,
    path_offsets,
    ring_centred,
)
from metairl_engine.motion.recording import DiscretiseSettings, demonstrations
from metairl_engine.sim.controller_patient import ControllerSettings, simulate_controller_patient
from metairl_engine.sim.patient import (
    DIRECTION_PREFERENCE,
    PatientSettings,
    SyntheticPatient,
    simulate_patient,
)
from service.files.images import heatmap_png

ROOT = Path(__file__).resolve().parents[1]

GAMMA = 0.9
"""Discount of the learner's MDP (the tutorial's `POST /v1/mdps` value; the patient itself planned with 0.95)."""

CONFIG = FitConfig(sharing="huber")
"""The default config with the paper's Huber sharing (the service's job default)."""


@dataclass(frozen=True)
class SessionResult:
    """One session's fit: which directions had demonstrations, the result and its wall time."""

    name: str
    directions: list[str]
    trajectories: dict[str, list[Trajectory]]
    result: FitResult
    wall_s: float
    cpu_s: float

    def visited(self, *directions: str) -> np.ndarray:
        """The velocity-grid states the demonstrations of these directions (default: all) pass through, as
        `POST /v1/comparisons` with ``"states": "visited"`` takes them (sorted, unique)."""
        return np.unique(
            np.concatenate([t.states for d in directions or self.directions for t in self.trajectories[d]])
        )


def outward(trajectory: Trajectory, *, width: int, height: int) -> Trajectory:
    """The trajectory up to its cell farthest from the plate centre: the movement without its return."""
    x, y, _ = velocity_coords(trajectory.states, width=width, height=height)
    far = max(int(np.argmax(np.hypot(x - width // 2, y - height // 2))), 1)
    return Trajectory.of(trajectory.states[: far + 1], trajectory.actions[:far])


def fit_session(patient: SyntheticPatient, name: str, *, outward_only: bool) -> SessionResult:
    """Cut one session into per-direction demonstrations and fit all directions together."""
    w, h = patient.width, patient.height
    demos = demonstrations(patient.sessions[name], discretise_settings=DiscretiseSettings(width=w, height=h))
    mdp = grid_mdp(width=w, height=h, velocity=True, gamma=GAMMA)
    directions = [d for d in DIRECTION_NAMES if d in demos.by_label]
    by_label = {
        d: [outward(t, width=w, height=h) for t in demos.by_label[d]] if outward_only else demos.by_label[d]
        for d in directions
    }
    tasks = [TaskData(mdp=mdp, trajectories=by_label[d], name=d) for d in directions]
    started, cpu_started = time.perf_counter(), time.process_time()
    result = fit(tasks, CONFIG, progress=partial(report_progress, name))
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu_started
    return SessionResult(
        name=name, directions=directions, trajectories=by_label, result=result, wall_s=wall, cpu_s=cpu
    )


def report_progress(session: str, progress: Progress) -> None:
    """Print every 25th step of a fit (a full-size fit runs for minutes)."""
    if progress.step % 25 == 0:
        print(
            f"{session}: step {progress.step} loss {progress.loss:.4f} held-out NLL {progress.heldout_nll} "
            f"{progress.elapsed_s:.0f} s",
            flush=True,
        )


def visited_and_all(learned: np.ndarray, target: np.ndarray, visited: np.ndarray) -> str:
    """``"r_visited / r_all"``: Pearson of ``learned`` with ``target`` on the ``visited`` states, and on all."""
    return f"{pearson(learned[visited], target[visited]):.2f} / {pearson(learned, target):.2f}"


def table_head() -> list[str]:
    """The header rows of a per-session table: a column per direction, then the baseline ("origin")."""
    header = ["session", *DIRECTION_NAMES, "origin (baseline)"]
    return ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]


def table(patient: SyntheticPatient, sessions: list[SessionResult], *, truth: str) -> list[str]:
    """Markdown rows: per session, Pearson of each direction's reward with ``truth`` ("ideal" or "task"),
    as "on the states its demonstrations visit / on all states" (the baseline: all the session's)."""
    lines = table_head()
    for s in sessions:
        cells = [s.name]
        for d in DIRECTION_NAMES:
            if d not in s.directions:
                cells.append("–")
                continue
            target = patient.ideal_reward if truth == "ideal" else patient.task_rewards[d]
            cells.append(visited_and_all(s.result.rewards[s.directions.index(d)], target, s.visited(d)))
        cells.append(visited_and_all(s.result.baseline, patient.ideal_reward, s.visited()))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def preference_table(patient: SyntheticPatient, sessions: list[SessionResult]) -> list[str]:
    """Markdown rows: per session, Pearson over the 8 velocity channels between each learned reward's channel
    means (all states) and the patient's preference per direction of motion."""
    lines = table_head()
    truth = np.asarray(patient.direction_preference)
    for s in sessions:
        rewards = dict(zip(s.directions, s.result.rewards, strict=True))
        learned = [rewards.get(d) for d in DIRECTION_NAMES] + [s.result.baseline]
        cells = [
            "–" if r is None else f"{pearson(r.reshape(8, -1).mean(axis=1), truth):.2f}" for r in learned
        ]
        lines.append("| " + " | ".join([s.name, *cells]) + " |")
    return lines


def save_heatmaps(patient: SyntheticPatient, sessions: list[SessionResult], folder: Path) -> list[Path]:
    """One PNG per session and direction (8 velocity panels, demonstrations drawn), baselines and the ideal."""
    folder.mkdir(parents=True, exist_ok=True)
    layout = Layout(width=patient.width, height=patient.height, channels=8)
    written = []

    def save(
        filename: str, values: np.ndarray, title: str, trajectories: list[np.ndarray] | None = None
    ) -> None:
        path = folder / filename
        path.write_bytes(heatmap_png(values, layout=layout, title=title, trajectories=trajectories))
        written.append(path)

    save("ideal.png", patient.ideal_reward, "ideal reward of the synthetic patient")
    for s in sessions:
        save(f"{s.name}-baseline.png", s.result.baseline, f"{s.name}: learned baseline")
        for i, d in enumerate(s.directions):
            states = [t.states for t in s.trajectories[d]]
            save(f"{s.name}-{d.replace(' ', '-')}.png", s.result.rewards[i], f"{s.name}: {d}", states)
    return written


def report(
    patient: SyntheticPatient, sessions: list[SessionResult], *, command: str, outward_only: bool
) -> str:
    """The MOTION.md text: set-up, both tables and timings."""
    n_states = 8 * patient.width * patient.height
    timing = [
        f"| {s.name} | {len(s.directions)} | {sum(len(s.trajectories[d]) for d in s.directions)} | {len(s.result.history)} | "
        f"{s.result.best_step} | {s.wall_s:.1f} s ({s.wall_s / 60:.1f} min) | {s.cpu_s / 60:.1f} min | "
        f"{s.wall_s / len(s.result.history):.2f} s |"
        for s in sessions
    ]
    return "\n".join(
        [
            "# Motion analysis: the paper's Table I on the synthetic patient",
            "",
            f"Tables generated by `{command}`.",
            "",
            f"- MDP: velocity grid {patient.width}×{patient.height} = {n_states:,} states, 8 actions, "
            f"gamma {GAMMA}; features: normalised (x, y) + direction one-hot.",
            f"- Patient: `simulate_patient(PatientSettings(width={patient.width}, height={patient.height}))` — "
            "8 instructions × 3 repetitions per session, 100 Hz COP with sway and sensor noise; its ideal reward "
            "is a map of places plus a preference per direction of motion.",
            "- Pipeline: `metairl_engine.motion.recording.demonstrations` (discretise, fill skipped cells, drop pauses, "
            "segment at peaks of the distance from the plate centre, label by instruction)"
            + (
                "; then each movement cut at its farthest cell and only the outward half kept (`--outward-only`)."
                if outward_only
                else ": out-and-back movements, as the service stores them."
            ),
            f'- Fit: `metairl_engine.fit.fit` with `FitConfig(sharing="huber")` (all other settings default: '
            f"hidden {list(CONFIG.hidden)}, lr {CONFIG.learning_rate}, max_steps {CONFIG.max_steps}, hold-out "
            f"{CONFIG.holdout_fraction}, patience {CONFIG.patience}), one fit per session over all its directions.",
            f"- Machine: {platform.machine()}, {os.cpu_count()} cores (shared with other work while measured), "
            f"torch {torch.__version__} with {torch.get_num_threads()} threads.",
            "",
            "## Pearson correlation of each recovered task reward with the ideal reward",
            "",
            "Table I's measure: how much of the patient's inherent preference each direction's learned reward "
            'carries. "origin (baseline)" is the learned baseline reward against the ideal reward.',
            "",
            *table(patient, sessions, truth="ideal"),
            "",
            "## Pearson correlation of each recovered task reward with that direction's true task reward",
            "",
            "The simulation also knows each task's own reward (ideal + a goal bump in the instructed "
            "direction), which the paper's real patients do not.",
            "",
            *table(patient, sessions, truth="task"),
            "",
            "## Pearson correlation of each learned reward's channel means with the direction preference",
            "",
            "The ideal reward includes a preference per direction of motion (`PatientSettings.direction_preference`:"
            f" {', '.join(f'{v:+.1f}' for v in patient.direction_preference)} by direction index). Here each learned "
            "reward is averaged over every velocity channel (8 values) and correlated with it.",
            "",
            *preference_table(patient, sessions),
            "",
            "## Wall time",
            "",
            "| session | directions | segments | steps run | step kept | wall time of the fit | CPU time "
            "(all threads) | wall time per step |",
            "| --- | --- | --- | --- | --- | --- | --- | --- |",
            *timing,
            "",
            f"Load average while measuring (1, 5, 15 min): {', '.join(f'{v:.1f}' for v in os.getloadavg())} on "
            f"{os.cpu_count()} cores: wall times include waiting for other processes; CPU time does not.",
            "",
            "Heatmaps (one panel per velocity direction, that direction's demonstrations drawn) of every direction "
            "are written to `benchmarks/motion/`; the ideal reward, both baselines and both sessions' "
            "`forward` are committed.",
            "",
        ]
    )


def main() -> None:
    """Simulate, fit both sessions, write the table and the heatmaps."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=100, help="grid width = height (100: the paper's MDP)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the synthetic patient")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "MOTION.md")
    parser.add_argument("--images", type=Path, default=ROOT / "benchmarks" / "motion")
    parser.add_argument(
        "--outward-only",
        action="store_true",
        help="experiment: fit each movement's outward half only (the service keeps out-and-back segments)",
    )
    parser.add_argument(
        "--direction-preference",
        type=float,
        nargs=8,
        default=DIRECTION_PREFERENCE,
        metavar="R",
        help="the patient's reward per direction of motion, by direction index (all 0: a map of places only)",
    )
    args = parser.parse_args()
    preference = tuple(args.direction_preference)
    patient = simulate_patient(
        PatientSettings(width=args.size, height=args.size, seed=args.seed, direction_preference=preference)
    )
    sessions = []
    for name in patient.sessions:
        result = fit_session(patient, name, outward_only=args.outward_only)
        print(f"{name}: {len(result.directions)} directions, {result.wall_s:.1f} s", flush=True)
        sessions.append(result)
    command = (
        "python -m benchmarks.motion"
        + (f" --size {args.size}" if args.size != 100 else "")
        + (" --outward-only" if args.outward_only else "")
        + (
            ""
            if preference == DIRECTION_PREFERENCE
            else f" --direction-preference {' '.join(map(str, preference))}"
        )
    )
    text = report(patient, sessions, command=command, outward_only=args.outward_only)
    previous = args.out.read_text() if args.out.exists() else ""
    start = previous.find(f"<!-- {BLOCK} -->")
    args.out.write_text(text + ("\n" + previous[start:] if start >= 0 else ""))  # keep `identify`'s block
    print(text)
    for path in save_heatmaps(patient, sessions, args.images):
        print("wrote", path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)


# --- identifiability study ---------------------------------------------------------------------------------

VARIANTS: dict[str, FitConfig] = {
    "paper (huber, all states)": CONFIG,
    "paper, 4 sharing blocks": replace(CONFIG, sharing_blocks=4),
    "sharing on visited states": FitConfig(sharing="huber", sharing_states="visited"),
    "per-task offset (std)": FitConfig(sharing="std"),
    "cell baseline": FitConfig(sharing="huber", baseline_features=(0, 1)),
    "cell baseline, visited states": FitConfig(
        sharing="huber", baseline_features=(0, 1), sharing_states="visited"
    ),
}
"""Fit configs compared by ``identify`` (all else default); the keys are the table's names."""

IDENTIFY_JSON = ROOT / "benchmarks" / "motion" / "identifiability.json"
BLOCK = "identifiability"


GENERATORS = ("planner", "controller", "controller-null")
"""``identify``'s patients: `simulate_patient`, `simulate_controller_patient`, and the null check: the same
controller whose paths ignore its preference map (``preference_gain=0``; the weak side stays), so its
correlations are what the task structure alone gives a baseline against that map."""


def simulate(generator: str, size: int, seed: int) -> Any:
    """One of `GENERATORS`."""
    if generator == "planner":
        return simulate_patient(PatientSettings(width=size, height=size, seed=seed))
    gain = 0.0 if generator == "controller-null" else ControllerSettings().preference_gain
    return simulate_controller_patient(
        ControllerSettings(width=size, height=size, seed=seed, preference_gain=gain)
    )


def fit_directions(patient: Any, session: str, config: FitConfig) -> SessionFit:
    """Cut one session into per-direction demonstrations (out-and-back, as the service stores them) and fit
    all its directions together with ``config``."""
    w, h = patient.width, patient.height
    demos = demonstrations(
        patient.sessions[session], discretise_settings=DiscretiseSettings(width=w, height=h)
    )
    mdp = grid_mdp(width=w, height=h, velocity=True, gamma=GAMMA)
    paths = {d: demos.by_label[d] for d in DIRECTION_NAMES if d in demos.by_label}
    tasks = [TaskData(mdp=mdp, trajectories=ts, name=d) for d, ts in paths.items()]
    started = time.perf_counter()
    result = fit(tasks, config)
    wall = time.perf_counter() - started
    return SessionFit(result=result, paths=paths, mdp=mdp, width=w, height=h, wall_s=wall)


def identify_one(patient: Any, session: str, config: FitConfig) -> dict[str, Any]:
    """Fit one session with ``config``; Pearson of the learned baseline with the patient's inherent preference
    on the states all demonstrations visit, on all states, and per direction on that direction's states."""
    w, h = patient.width, patient.height
    found = fit_directions(patient, session, config)
    truth, base = patient.ideal_reward, found.result.baseline
    visited = found.union
    centred = {
        name: ring_centred(values, width=w, height=h, states=visited)
        for name, values in (("base", base), ("truth", truth))
    }
    return {
        "visited": pearson(base[visited], truth[visited]),
        "ring_centred": pearson(centred["base"], truth[visited]),
        "ring_centred_both": pearson(centred["base"], centred["truth"]),
        "all": pearson(base, truth),
        "per_direction": {d: pearson(base[s], truth[s]) for d, s in found.visited.items()},
        "steps": len(found.result.history),
        "wall_s": found.wall_s,
    }


def identify_table(entries: list[dict[str, Any]]) -> list[str]:
    """Markdown rows, one per (generator, variant, session): visited, all, per direction."""
    head = [
        "patient",
        "config",
        "session",
        "visited",
        "all states",
        "ring-centred vs preference",
        "ring-centred vs ring-centred",
        *DIRECTION_NAMES,
        "steps",
        "wall",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    order = {name: k for k, name in enumerate(VARIANTS)}
    for e in sorted(
        entries, key=lambda e: (e["generator"], e["size"], e["seed"], order.get(e["variant"], 99))
    ):
        per = [f"{e['per_direction'][d]:+.2f}" if d in e["per_direction"] else "–" for d in DIRECTION_NAMES]
        constant = all(v == 0.0 for v in e["per_direction"].values())  # pearson's 0.0 of a constant vector
        cells = [
            f"{e['generator']} {e['size']}×{e['size']} seed {e['seed']}",
            e["variant"],
            e["session"],
            f"**{e['visited']:+.2f}**" + (" (constant baseline)" if constant else ""),
            f"{e['all']:+.2f}",
            f"{e['ring_centred']:+.2f}",
            f"{e['ring_centred_both']:+.2f}",
            *per,
            str(e["steps"]),
            f"{e['wall_s']:.0f} s",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def readout_table(generator: str, size: int, seed: int, images: Path) -> list[str]:
    """Markdown rows: peak reach per direction (mean [95 % interval], plate metres) of both sessions, and
    stimulated minus unstimulated; draws the comparison figure to ``images/comparison-<generator>.png``."""
    patient = simulate(generator, size, seed)
    comparison = compare_recordings([patient.sessions["unstimulated"]], [patient.sessions["stimulated"]])
    images.mkdir(parents=True, exist_ok=True)
    png = comparison_png(comparison, names=("unstimulated", "stimulated"), units="m")
    (images / f"comparison-{generator}.png").write_bytes(png)

    def fmt(v: dict[str, Any]) -> str:
        return (
            f"{v['mean']:.3f} [{v['low']:.3f}, {v['high']:.3f}]"
            if v["low"] is not None
            else f"{v['mean']:.3f}"
        )

    lines = ["| " + " | ".join(["peak reach (m)", *DIRECTION_NAMES]) + " |", "|" + " --- |" * 9]
    for side, name in (("a", "unstimulated"), ("b", "stimulated")):
        rows = {r["direction"]: r for r in comparison[side]["directions"]}
        cells = [fmt(rows[d]["peak_reach"]) if d in rows else "–" for d in DIRECTION_NAMES]
        lines.append("| " + " | ".join([name, *cells]) + " |")
    rows = {r["direction"]: r for r in comparison["directions"]}
    diffs = [fmt(rows[d]["peak_reach_diff"]) if d in rows else "–" for d in DIRECTION_NAMES]
    lines.append("| " + " | ".join(["stimulated − unstimulated", *diffs]) + " |")
    return lines


def radial_share_table(size: int, seed: int) -> list[str]:
    """Markdown rows: per patient and session, the radial share of the preference's variance on visited states."""
    lines = ["| patient | session | visited states | radial share |", "| --- | --- | --- | --- |"]
    for generator in ("planner", "controller"):
        patient = simulate(generator, size, seed)
        for session, rec in patient.sessions.items():
            demos = demonstrations(rec, discretise_settings=DiscretiseSettings(width=size, height=size))
            visited = np.unique(np.concatenate([t.states for ts in demos.by_label.values() for t in ts]))
            truth = patient.ideal_reward[visited]
            centred = ring_centred(patient.ideal_reward, width=size, height=size, states=visited)
            lines.append(
                f"| {generator} | {session} | {len(visited)} | {1 - centred.var() / truth.var():.2f} |"
            )
    return lines


def identify_commands(entries: list[dict[str, Any]]) -> list[str]:
    """The ``identify`` commands that reproduce ``entries``: one per (size, seed, generator), naming the
    variants unless all of `VARIANTS` were run."""
    out = []
    for size, seed, generator in sorted({(e["size"], e["seed"], e["generator"]) for e in entries}):
        ran = {
            e["variant"] for e in entries if (e["size"], e["seed"], e["generator"]) == (size, seed, generator)
        }
        variants = (
            "" if ran >= set(VARIANTS) else " --variants " + " ".join(f"'{v}'" for v in VARIANTS if v in ran)
        )
        out.append(
            f"`python -m benchmarks.motion identify --size {size} --seed {seed} --generators {generator}{variants}`"
        )
    return out


def write_block(path: Path, name: str, text: str) -> None:
    """Replace the text between ``<!-- name -->`` and ``<!-- /name -->`` in ``path`` (appended if absent)."""
    start, end = f"<!-- {name} -->", f"<!-- /{name} -->"
    old = path.read_text() if path.exists() else ""
    block = f"{start}\n{text}\n{end}"
    if start in old and end in old:
        new = old[: old.index(start)] + block + old[old.index(end) + len(end) :]
    else:
        new = old.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(new)


def identify_main(argv: list[str]) -> None:
    """``identify``: fit each generator's sessions with each variant; results accumulate in a JSON file and
    the whole table is rewritten into MOTION.md's identifiability block."""
    parser = argparse.ArgumentParser(prog="motion.py identify", description="baseline vs inherent preference")
    parser.add_argument("--size", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--generators", nargs="+", default=["planner", "controller"], choices=GENERATORS)
    parser.add_argument(
        "--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS), metavar="NAME"
    )
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "MOTION.md")
    parser.add_argument("--json", type=Path, default=IDENTIFY_JSON, help="where results accumulate")
    parser.add_argument(
        "--only-table", action="store_true", help="rewrite the block from the JSON, fit nothing"
    )
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    entries: list[dict[str, Any]] = json.loads(args.json.read_text()) if args.json.exists() else []
    for generator in [] if args.only_table else args.generators:
        patient = simulate(generator, args.size, args.seed)
        for variant in args.variants:
            for session in patient.sessions:
                found = identify_one(patient, session, VARIANTS[variant])
                key = {"generator": generator, "size": args.size, "seed": args.seed, "variant": variant}
                # re-read: another identify run (other generator) may have added rows meanwhile
                entries = json.loads(args.json.read_text()) if args.json.exists() else []
                entries = [e for e in entries if {k: e[k] for k in key} != key or e["session"] != session]
                entries.append({**key, "session": session, **found})
                print(f"{generator} {variant} {session}: visited {found['visited']:+.2f}", flush=True)
                args.json.parent.mkdir(parents=True, exist_ok=True)
                args.json.write_text(json.dumps(entries, indent=1))
    configs = sorted({(e["size"], e["seed"]) for e in entries})
    text = [
        "## Identifiability: the learned baseline against the inherent preference",
        "",
        "Pearson correlation of the learned baseline reward with the patient's inherent preference "
        "(`ideal_reward`) on the velocity-grid states all demonstrations visit (**visited**), on all states, "
        "and per instructed direction on that direction's states. One fit per session over all directions, "
        f"gamma {GAMMA}, out-and-back segments as the service stores them. Rows come from "
        + "; ".join(identify_commands(entries))
        + " (results accumulate in `benchmarks/motion/identifiability.json`; `--only-table` rewrites this "
        "block from it). The planner is `simulate_patient` (plans on the velocity "
        "grid; its preference is a cell map plus a preference per direction of motion), the controller "
        "`simulate_controller_patient` (no planning; its preference is a cell map only). docs/motion.md "
        "explains the configs.",
        "",
        *identify_table(entries),
        "",
        "### The kinematic readout on the same recordings",
        "",
        "Peak reach per instructed direction (`metairl_engine.motion.kinematics.compare_recordings`, mean over the 3 "
        "repetitions with its 95 % bootstrap interval). The controller's weak side is `left`. All five "
        "descriptors of both patients are drawn in `benchmarks/motion/comparison-planner.png` and "
        "`comparison-controller.png` (`comparison_png`).",
        "",
    ]
    text += [
        "### Radial share",
        "",
        "Share of the inherent preference's variance on the visited states that is a function of the distance "
        "from the centre alone (1 − var(`ring_centred`(preference)) / var(preference)): the part no fit can "
        "tell from moving out to the instructed distance.",
        "",
        *radial_share_table(*configs[-1]),
        "",
    ]
    for generator in ("planner", "controller"):
        text += [f"{generator}, {configs[-1][0]}×{configs[-1][0]}, seed {configs[-1][1]}:", ""]
        text += [*readout_table(generator, *configs[-1], ROOT / "benchmarks" / "motion"), ""]
    write_block(args.out, BLOCK, "\n".join(text))
    print("\n".join(text))


# --- does the learned readout agree with the recordings? ---------------------------------------------------

AGREEMENT_PATIENTS: dict[str, str | None] = {
    "planner": None,
    "controller, weak left": "left",
    "controller, weak right": "right",
    "controller, weak forward left": "forward left",
}
"""``agreement``'s patients: the controller's weak side (None: the planner, `simulate_patient`). The forward-left controller was added for this check
and never used to choose anything."""


def agreement_patient(name: str, size: int, seed: int, *, null: bool = False) -> Any:
    """One of `AGREEMENT_PATIENTS`; ``null``: the same controller whose paths ignore its preference
    (``preference_gain=0``)."""
    weak = AGREEMENT_PATIENTS[name]
    if weak is None:
        return simulate("planner", size, seed)
    settings = ControllerSettings(width=size, height=size, seed=seed, weak_side=weak)
    return simulate_controller_patient(replace(settings, preference_gain=0.0) if null else settings)


def agreement_one(patient: Any, session: str) -> dict[str, Any]:
    """Fit one session with the default config; the learned per-direction readout, the same readout of the
    patient's true preference (``ideal_reward``), their Spearman, and the verdict against the peak reach and
    the path bend (and, beside it, the verdict the reach alone gives)."""
    w, h = patient.width, patient.height
    rec = patient.sessions[session]
    found = fit_directions(patient, session, FitConfig())
    directions, visited = found.directions, found.visited
    learned = direction_readout(found.result.baseline, visited, width=w, height=h)
    truth = direction_readout(patient.ideal_reward, visited, width=w, height=h)
    bend = path_bend(visited, width=w, height=h)
    reach: dict[str, list[float]] = {}
    for m in movements(rec):
        reach.setdefault(m.direction, []).append(m.peak_reach)
    offsets = path_offsets({d: [t.states for t in found.paths[d]] for d in directions}, width=w, height=h)
    verdict = agreement(learned, reach, offsets=offsets)
    both = [d for d in directions if d in reach]
    return {
        "truth_reach": float(spearmanr([truth[d] for d in both], [np.mean(reach[d]) for d in both])[0]),
        "learned": learned,
        "truth": truth,
        "spearman_truth": float(
            spearmanr([learned[d] for d in directions], [truth[d] for d in directions])[0]
        ),
        "bend": bend,
        "spearman_bend_truth": float(
            spearmanr([bend[d] for d in directions], [truth[d] for d in directions])[0]
        )
        if bend
        else None,
        "verdict": verdict.verdict,
        "verdict_reach_alone": agreement(learned, reach).verdict,
        "spearman_reach": verdict.spearman,
        "spearman_bend": verdict.bend_spearman,
        "detail": verdict.detail,
        "wall_s": found.wall_s,
    }


def verdict_correct(verdict: str, rho: float) -> str:
    """Whether a verdict is right about a readout whose Spearman with the truth is ``rho``: agrees needs ρ > 0,
    disagrees ρ < 0; undetermined claims nothing."""
    if verdict == "undetermined":
        return "– (no claim)"
    return "yes" if (rho > 0) == (verdict == "agrees") else "**no**"


def agreement_main(argv: list[str]) -> None:
    """``agreement``: per patient and session, the learned readout's Spearman with the true preference and the
    verdict; the table replaces MOTION.md's agreement block."""
    parser = argparse.ArgumentParser(
        prog="motion.py agreement", description="learned readout vs truth, verdict"
    )
    parser.add_argument("--size", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--patients", nargs="+", default=list(AGREEMENT_PATIENTS), choices=list(AGREEMENT_PATIENTS)
    )
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "MOTION.md")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    rows, claims, right, alone_claims, alone_right = [], 0, 0, 0, 0
    for name in args.patients:
        patient = agreement_patient(name, args.size, args.seed)
        for session in patient.sessions:
            found = agreement_one(patient, session)
            print(f"{name} {session}: {json.dumps(found)}", flush=True)
            claims += found["verdict"] != "undetermined"
            right += verdict_correct(found["verdict"], found["spearman_truth"]) == "yes"
            alone_claims += found["verdict_reach_alone"] != "undetermined"
            alone_right += verdict_correct(found["verdict_reach_alone"], found["spearman_truth"]) == "yes"
            bend, vs_bend = found["spearman_bend_truth"], found["spearman_bend"]
            rows.append(
                f"| {name} | {session} | {found['spearman_truth']:+.2f} | {found['spearman_reach']:+.2f} | "
                f"{'–' if vs_bend is None else f'{vs_bend:+.2f}'} | {found['truth_reach']:+.2f} | "
                f"{'–' if bend is None else f'{bend:+.2f}'} | {found['verdict']} | "
                f"{verdict_correct(found['verdict'], found['spearman_truth'])} | {found['verdict_reach_alone']} | "
                f"{verdict_correct(found['verdict_reach_alone'], found['spearman_truth'])} | {found['wall_s']:.0f} s |"
            )
    text = [
        "## Does the learned readout agree with the recordings?",
        "",
        f"`python -m benchmarks.motion agreement --size {args.size} --seed {args.seed}`: one fit per session with the "
        "default config, gamma 0.9, on the service's out-and-back segments. **vs truth**: Spearman of the learned "
        "per-direction readout (`direction_readout` of the baseline, the service's `baseline_ring_centred`) "
        "with the same readout of the patient's true preference (`ideal_reward`). **vs reach**: Spearman of the "
        "learned readout with the mean peak reach and **vs bend** with the path-bend levels of the mean "
        "per-repetition bend, the two the verdict (`agreement`, docs/motion.md) tests; **truth vs reach**: how "
        "well the reach ranks the true preference; **path bend vs truth**: Spearman of the model-free "
        "`path_bend` readout (the service's `path_bend`, docs/motion.md) with the truth. **reach alone**: the "
        "verdict that tests the reach only, for comparison. A verdict is right when `agrees` goes with "
        "ρ(truth) > 0 and `disagrees` with ρ(truth) < 0.",
        "",
        "| patient | session | vs truth | vs reach | vs bend | truth vs reach | path bend vs truth | verdict "
        "| verdict right | reach alone | reach alone right | wall |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        *rows,
        "",
        f"Verdict accuracy: {claims} claim(s) in {len(rows)} sessions, {right} right (reach alone: "
        f"{alone_claims} claim(s), {alone_right} right); `undetermined` ({len(rows) - claims}) claims nothing "
        "and tells the user not to read the learned ranking as the patient's preference.",
    ]
    write_block(args.out, "agreement", "\n".join(text))
    print("\n".join(text))


def bend_one(patient: Any, session: str, truth_reward: np.ndarray) -> tuple[float, float] | None:
    """Spearman of `path_bend` and of the mean peak reach with the per-direction truth (`direction_readout` of
    ``truth_reward``) for one session; None where a direction has no demonstrations."""
    w, h = patient.width, patient.height
    rec = patient.sessions[session]
    demos = demonstrations(rec, discretise_settings=DiscretiseSettings(width=w, height=h))
    if any(d not in demos.by_label for d in DIRECTION_NAMES):
        return None
    visited = {d: np.unique(np.concatenate([t.states for t in demos.by_label[d]])) for d in DIRECTION_NAMES}
    truth = direction_readout(truth_reward, visited, width=w, height=h)
    bend = path_bend(visited, width=w, height=h)
    reach: dict[str, list[float]] = {}
    for m in movements(rec):
        reach.setdefault(m.direction, []).append(m.peak_reach)
    ranked = [truth[d] for d in DIRECTION_NAMES]
    return (
        float(spearmanr([bend[d] for d in DIRECTION_NAMES], ranked)[0]),
        float(spearmanr([np.mean(reach[d]) for d in DIRECTION_NAMES], ranked)[0]),
    )


def bend_main(argv: list[str]) -> None:
    """``bend``: no fits; over seeds, how well `path_bend` and the peak reach rank each patient's true
    per-direction preference, with the null controllers (paths that ignore the preference) beside; the table
    replaces MOTION.md's path-bend block."""
    parser = argparse.ArgumentParser(prog="motion.py bend", description="path bend vs truth over seeds")
    parser.add_argument("--size", type=int, default=30)
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "MOTION.md")
    args = parser.parse_args(argv)
    rows = []
    cases = [
        (name, null)
        for name, weak in AGREEMENT_PATIENTS.items()
        for null in (False, True)
        if weak or not null
    ]
    for name, null in cases:
        found: dict[str, list[tuple[float, float]]] = {}
        for seed in range(args.seeds):
            patient = agreement_patient(name, args.size, seed, null=null)
            truth = patient.ideal_reward  # the null patient's preference is the one it ignores
            for session in patient.sessions:
                one = bend_one(patient, session, truth)
                if one is not None:
                    found.setdefault(session, []).append(one)
        label = f"{name}, paths ignore the preference (null)" if null else name
        for session, values in found.items():
            bend, reach = np.array(values).T
            rows.append(
                f"| {label} | {session} | {len(values)} | {bend.mean():+.2f} [{bend.min():+.2f}, {bend.max():+.2f}] "
                f"| {reach.mean():+.2f} [{reach.min():+.2f}, {reach.max():+.2f}] |"
            )
            print(rows[-1], flush=True)
    text = [
        "## Path bend: the preference ranked from the recordings, without a fit",
        "",
        f"`python -m benchmarks.motion bend --size {args.size} --seeds {args.seeds}`: no fits. Per patient and "
        f'session, over seeds 0–{args.seeds - 1}: Spearman of `path_bend` (docs/motion.md, "Path bend") and of '
        "the mean peak reach with the true per-direction preference (the agreement block's truth), mean "
        "[min, max] over seeds. The null rows are the same controllers whose paths ignore the preference "
        "(`preference_gain=0`), scored against the preference they ignore: what the readout gives with "
        "nothing to read. The weak forward-left controller and the planner were never used to choose anything.",
        "",
        "| patient | session | seeds | path bend vs truth | reach vs truth |",
        "| --- | --- | --- | --- | --- |",
        *rows,
    ]
    write_block(args.out, "path-bend", "\n".join(text))
    print("\n".join(text))


# --- readings of the fit against the true preference ---------------------------------------------------------

READINGS_PATIENTS = ("controller, weak left", "controller, weak right")
"""The tuning controllers whose agreement fits the readings are scored on (docs/motion.md)."""


@dataclass(frozen=True)
class SessionReadings:
    """One session: each reading's Spearman with the true preference (``scores``), the paths' mean offsets
    from their instructed lines (cells, `motion_readings.offsets`), the demonstrated sideways drift per
    direction (cells per step) and its Spearman with the learned policies' drift, and the fit's wall time."""

    scores: dict[str, float]
    offsets: dict[str, float]
    drift: dict[str, float]
    drift_spearman: float
    wall_s: float


def session_readings(
    patient: Any, *, config: FitConfig | None = None, readings: dict[str, Reading] | None = None
) -> dict[str, SessionReadings]:
    """Per session of ``patient``: fit it as `agreement` does (``config`` default: `FitConfig()`) and score
    every reading (default: `READINGS` then `COMPARISON`) against ``patient.ideal_reward``'s per-direction
    readout."""
    found = {}
    for session in patient.sessions:
        fitted = fit_directions(patient, session, config or FitConfig())
        drift = demonstrated_drift(fitted)
        found[session] = SessionReadings(
            scores=score(fitted, patient.ideal_reward, readings or READINGS | COMPARISON),
            offsets=offsets(fitted),
            drift=drift,
            drift_spearman=spearman(policy_drift(fitted), drift),
            wall_s=fitted.wall_s,
        )
    return found


def readings_main(argv: list[str]) -> None:
    """``readings``: fit both sessions of the tuning controllers and of the weak-left null controller; every
    reading's Spearman with the truth; the table replaces MOTION.md's readings block."""
    parser = argparse.ArgumentParser(prog="motion.py readings", description="readings of the fit vs truth")
    parser.add_argument("--size", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "MOTION.md")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    columns: dict[str, SessionReadings] = {}
    cases = [(name, False) for name in READINGS_PATIENTS] + [(READINGS_PATIENTS[0], True)]
    for name, null in cases:
        patient = agreement_patient(name, args.size, args.seed, null=null)
        for session, found in session_readings(patient).items():
            label = f"{name.removeprefix('controller, ')}{' (null)' if null else ''}, {session}"
            columns[label] = found
            print(f"{label}: {json.dumps(found.scores)} ({found.wall_s:.0f} s)", flush=True)
    tuning = [c for label, c in columns.items() if "(null)" not in label]
    positive = [name for name in READINGS if all(c.scores[name] > 0 for c in tuning)]
    null_columns = [c for label, c in columns.items() if "(null)" in label]
    null_positive = sum(all(c.scores[name] > 0 for c in null_columns) for name in READINGS)
    rows = []
    for name, reading in (READINGS | COMPARISON).items():
        cells = [f"{c.scores[name]:+.2f}" for c in columns.values()]
        rows.append(f"| {name} | {' | '.join(cells)} | {' '.join((reading.__doc__ or '').split())} |")
    paths = []
    for label, c in columns.items():
        size = np.abs(list(c.offsets.values()))
        drift = np.abs(list(c.drift.values())).max()
        paths.append(
            f"| {label} | {size.mean():.2f} [{size.min():.2f}, {size.max():.2f}] | {drift:.3f} | "
            f"{c.drift_spearman:+.2f} | {c.wall_s:.0f} s |"
        )
    text = [
        "## Readings of the fit against the true preference",
        "",
        f"`python -m benchmarks.motion readings --size {args.size} --seed {args.seed}`: both sessions of the "
        "tuning controllers (weak left, weak right) and of the weak-left controller whose paths ignore its "
        "preference (null, `preference_gain=0`), each fitted as `agreement` fits them (default config, gamma "
        "0.9, out-and-back segments). Each reading (`benchmarks/motion_readings.py`) gives one value per "
        "direction; the table is its Spearman with the true per-direction preference (the agreement block's "
        'truth) over the 8 directions. "As served": ring-centred (1-cell rings) over the states all '
        "directions visit and averaged over each direction's visited states, as the served "
        '`baseline_ring_centred`; "summed around the centre": per-direction slopes turned into levels by '
        "`bend_levels`, as `path_bend` turns the paths' offsets. The last row is `path_bend` itself.",
        "",
        "| reading | " + " | ".join(columns) + " | what it is |",
        "|" + " --- |" * (len(columns) + 2),
        *rows,
        "",
        "Readings of the fit positive in all four sessions of the tuning controllers: "
        + (", ".join(positive) if positive else "none")
        + f"; in both sessions of the null controller, whose paths ignore the preference: {null_positive} of "
        f"{len(READINGS)}.",
        "",
        "The paths: mean absolute offset of each direction's visited cells from its instructed line (cells; mean "
        "[min, max] over the 8 directions, `motion_readings.offsets`, what `path_bend` reads); the largest "
        "demonstrated sideways drift of a direction (`demonstrated_drift`, cells per step: a path that returns "
        "to the centre moves as far to one side as back, so its mean sideways move is near 0 even where it "
        "bends) and its Spearman with the learned policies' drift (`policy_drift`); the fit's wall time:",
        "",
        "| session | offset from the instructed line | demonstrated drift, largest | policies' drift vs "
        "demonstrated drift | wall |",
        "| --- | --- | --- | --- | --- |",
        *paths,
    ]
    write_block(args.out, "readings", "\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "identify":
        identify_main(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "agreement":
        agreement_main(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "bend":
        bend_main(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "readings":
        readings_main(sys.argv[2:])
    else:
        main()
