"""The paper's Table I on the synthetic patient, through the engine directly (no service).

For each session (unstimulated, stimulated) of `metairl_engine.patient.simulate_patient`, the COP recording is
cut into per-direction demonstrations (`metairl_engine.motion.demonstrations`) and one meta-IRL fit with Huber
sharing and the default config learns a reward per instructed direction plus the baseline on the velocity
grid (100×100 = 80,000 states by default). The table gives the Pearson correlation of every recovered task
reward with the patient's ideal reward, and of the baseline with it (the paper's "origin" column), on the
states the demonstrations visit and on all states, with the wall time of each session's fit. Usage::

    .venv/bin/python benchmarks/motion.py [--size 100] [--seed 0] [--out benchmarks/MOTION.md]
        [--images benchmarks/motion] [--outward-only] [--direction-preference R R R R R R R R]

``--size 30`` (7,200 states) runs in a few minutes for a quick look; only 100 reproduces the paper's MDP.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import torch  # noqa: E402

from metairl_engine import FitConfig, Layout, Trajectory  # noqa: E402
from metairl_engine.fit import FitResult, Progress, TaskData, fit  # noqa: E402
from metairl_engine.grids import DIRECTION_NAMES, grid_mdp, velocity_coords  # noqa: E402
from metairl_engine.metrics import pearson  # noqa: E402
from metairl_engine.motion import DiscretiseSettings, demonstrations  # noqa: E402
from metairl_engine.patient import (  # noqa: E402
    DIRECTION_PREFERENCE,
    PatientSettings,
    SyntheticPatient,
    simulate_patient,
)
from service.render import heatmap_png  # noqa: E402

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
            "- Pipeline: `metairl_engine.motion.demonstrations` (discretise, fill skipped cells, drop pauses, "
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
        "python benchmarks/motion.py"
        + (f" --size {args.size}" if args.size != 100 else "")
        + (" --outward-only" if args.outward_only else "")
        + (
            ""
            if preference == DIRECTION_PREFERENCE
            else f" --direction-preference {' '.join(map(str, preference))}"
        )
    )
    text = report(patient, sessions, command=command, outward_only=args.outward_only)
    args.out.write_text(text)
    print(text)
    for path in save_heatmaps(patient, sessions, args.images):
        print("wrote", path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)


if __name__ == "__main__":
    main()
