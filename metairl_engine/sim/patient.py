"""A seeded synthetic patient on a force plate, for tests and the demo (paper §IV-B, Table I).

The patient has a known inherent ("ideal") preference over velocity-grid states: a map of places on the plate
plus a preference per direction of motion (backward-left moves are costly), which is what a velocity-grid reward
can express. For each instructed direction a Boltzmann-rational agent on the velocity grid (actions ~
softmax(b·Q), Q planned with a max backup for the task reward = ideal baseline + a goal bump along that
direction) walks out, then back to the centre under a return reward; the walk is replayed as a continuous COP
with slow sway and sensor noise. The unstimulated session has weaker control (smaller b) and more sway than the
stimulated one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

from metairl_engine.errors import Issue, check, integer_issues
from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS, grid_mdp, velocity_coords, velocity_state
from metairl_engine.motion.recording import NO_INSTRUCTION, Bounds, Recording
from metairl_engine.planning import transition_matrix, value_iteration


@dataclass(frozen=True)
class SessionSettings:
    """One session's motor control: ``confidence`` b of softmax(b·Q); sway and noise std in grid cells."""

    name: str
    confidence: float
    sway: float
    noise: float


UNSTIMULATED = SessionSettings(name="unstimulated", confidence=4.0, sway=0.8, noise=0.25)
"""Weaker control, more sway."""

STIMULATED = SessionSettings(name="stimulated", confidence=10.0, sway=0.4, noise=0.15)
"""Sharper control under transcutaneous stimulation."""


DIRECTION_PREFERENCE = (0.0, 0.0, 0.3, 0.0, -0.3, -1.0, -0.3, 0.0)
"""The default inherent preference per direction of motion (by `DIRECTIONS` index): forward is easy, left,
backward and above all backward-left are costly."""


PLATE = Bounds(x_min=-0.2, x_max=0.2, y_min=-0.2, y_max=0.2)
"""A 40 cm × 40 cm force plate in metres, centred on the origin."""


@dataclass(frozen=True)
class ExperimentSettings:
    """What every simulated patient's experiment shares: the velocity grid, the plate, the instructions given,
    the sample rate and the seed."""

    width: int = 100
    height: int = 100
    bounds: Bounds = PLATE
    directions: tuple[str, ...] = DIRECTION_NAMES
    """Instructions given, in order; each is repeated ``repetitions`` times in a row."""
    repetitions: int = 3
    sample_rate: float = 100.0
    seed: int = 0

    def issues(self, pointer: str = "/patient") -> list[Issue]:
        """Unusable settings (a subclass adds the checks of its own fields)."""
        out = integer_issues(self, pointer, {"width": 8, "height": 8, "repetitions": 1})
        if not set(self.directions) <= set(DIRECTION_NAMES) or not self.directions:
            out.append(Issue(f"{pointer}/directions", f"must be some of {', '.join(DIRECTION_NAMES)}"))
        return out + self.bounds.issues(f"{pointer}/bounds")


@dataclass(frozen=True)
class PatientSettings(ExperimentSettings):
    """The planner patient's experiment: how it moves (times in seconds) on top of the shared settings."""

    reach: float = 0.5
    """How far the instructed goal lies from the centre, as a fraction of the plate's half-size."""
    goal_weight: float = 2.0
    """Height of the goal bump added to the baseline in each task reward."""
    direction_preference: tuple[float, ...] = DIRECTION_PREFERENCE
    """Reward added to every state entered moving in each direction (8 values by `DIRECTIONS` index)."""
    gamma: float = 0.95
    speed: float = 20.0
    """Cells crossed per second."""
    pause: float = 0.8
    """Rest at the centre before each movement."""
    sessions: tuple[SessionSettings, ...] = (UNSTIMULATED, STIMULATED)

    def issues(self, pointer: str = "/patient") -> list[Issue]:
        """Unusable settings."""
        out = super().issues(pointer)
        if not 0 < self.reach < 1:
            out.append(Issue(f"{pointer}/reach", "must be in (0, 1)"))
        if len(self.direction_preference) != len(DIRECTION_NAMES):
            out.append(Issue(f"{pointer}/direction_preference", f"must hold {len(DIRECTION_NAMES)} numbers"))
        return out


@dataclass(frozen=True, eq=False)
class SyntheticPatient:
    """Simulation output. Rewards are (8·height·width,) float64 over velocity-grid states.

    ``ideal_reward`` is the inherent baseline, whose part per direction of motion is ``direction_preference``
    (8 values by `DIRECTIONS` index); ``task_rewards`` {instruction: reward} drove the outward
    movements; ``sessions`` {name: Recording} hold the COP samples with their instruction column.
    """

    width: int
    height: int
    bounds: Bounds
    ideal_reward: np.ndarray
    direction_preference: tuple[float, ...]
    task_rewards: dict[str, np.ndarray]
    sessions: dict[str, Recording]


def _plate_coords(width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised coordinates u, v ∈ [-1, 1] of every cell ``y * width + x``: two (H·W,) arrays."""
    y, x = np.divmod(np.arange(width * height), width)
    return 2 * x / (width - 1) - 1, 2 * y / (height - 1) - 1


def _bump(u: np.ndarray, v: np.ndarray, centre: tuple[float, float], width: float) -> np.ndarray:
    """A Gaussian bump of height 1 at ``centre`` (normalised coordinates)."""
    return np.asarray(np.exp(-((u - centre[0]) ** 2 + (v - centre[1]) ** 2) / (2 * width**2)))


def _cell_ideal(width: int, height: int) -> np.ndarray:
    """The ideal preference per cell (H·W,): a broad bump at the centre, weak on the backward-left side."""
    u, v = _plate_coords(width, height)
    return _bump(u, v, (0.0, 0.0), 0.5) - 0.8 * _bump(u, v, (-0.5, -0.4), 0.3)


def ideal_reward(
    *, width: int, height: int, direction_preference: tuple[float, ...] = DIRECTION_PREFERENCE
) -> np.ndarray:
    """The patient's inherent preference over velocity-grid states (8·H·W,): the cell map of `_cell_ideal` in
    every direction channel plus that channel's ``direction_preference``."""
    return np.tile(_cell_ideal(width, height), 8) + np.repeat(direction_preference, width * height)


def _goal(direction: str, reach: float) -> tuple[float, float]:
    """Where an instruction points, in normalised coordinates, ``reach`` from the centre."""
    d = DIRECTIONS[DIRECTION_NAMES.index(direction)]
    unit = d / np.hypot(d[0], d[1])
    return float(unit[0] * reach), float(unit[1] * reach)


def simulate_patient(settings: PatientSettings = PatientSettings()) -> SyntheticPatient:
    """Plan every instruction's task on the velocity grid, then record each session's COP (deterministic
    given ``seed``).

    A velocity-grid move does not depend on the current velocity, so Q(s, a) = r(s') + γV(s') is the same in
    every velocity channel of a cell: the walk uses channel 0's rows as the cell's Q, with the 8-move cell
    grid (same action order as `DIRECTIONS`) for the next cell.
    """
    check(settings.issues())
    w, h = settings.width, settings.height
    n_cells = w * h
    transitions = transition_matrix(grid_mdp(width=w, height=h, velocity=True, gamma=settings.gamma))
    u, v = _plate_coords(w, h)
    base = ideal_reward(width=w, height=h, direction_preference=settings.direction_preference)
    goals = {d: _goal(d, settings.reach) for d in settings.directions}
    goals[NO_INSTRUCTION] = (0.0, 0.0)  # back to the centre
    task = {name: base + settings.goal_weight * np.tile(_bump(u, v, g, 0.2), 8) for name, g in goals.items()}
    q = {
        name: value_iteration(transitions, r, gamma=settings.gamma, backup="max", tolerance=1e-4).q[:n_cells]
        for name, r in task.items()
    }
    cells = grid_mdp(width=w, height=h, moves=8, gamma=settings.gamma)
    assert cells.next_state is not None
    rng = np.random.default_rng(settings.seed)
    sessions = {s.name: _record_session(settings, s, cells.next_state, q, rng) for s in settings.sessions}
    return SyntheticPatient(
        width=w,
        height=h,
        bounds=settings.bounds,
        ideal_reward=base,
        direction_preference=settings.direction_preference,
        task_rewards={d: task[d] for d in settings.directions},
        sessions=sessions,
    )


def _record_session(
    settings: PatientSettings,
    session: SessionSettings,
    next_cell: np.ndarray,
    q: dict[str, np.ndarray],
    rng: np.random.Generator,
) -> Recording:
    """Walk every instructed movement on the grid (pause, out, back), then turn the walk into COP samples."""
    w, h = settings.width, settings.height
    y, x = np.divmod(np.arange(w * h), w)
    distance = np.hypot(x - w // 2, y - h // 2)  # of every cell from the centre cell, in cells
    reach = settings.reach * min(w, h) / 2
    walk = partial(_walk, next_cell=next_cell, distance=distance, confidence=session.confidence, rng=rng)
    states, times, labels = (
        [int(velocity_state(w // 2, h // 2, 0, width=w, height=h))],
        [0.0],
        [NO_INSTRUCTION],
    )
    for direction in settings.directions:
        for _ in range(settings.repetitions):
            states.append(states[-1])  # the pause: the instruction is given, the patient still rests
            times.append(times[-1] + settings.pause)
            labels.append(direction)
            out = walk(
                states[-1] % (w * h), q[direction], stop=lambda d: d >= 0.9 * reach, limit=int(4 * reach)
            )
            back = walk(out[-1] % (w * h), q[NO_INSTRUCTION], stop=lambda d: d <= 1.5, limit=int(6 * reach))
            states += out + back
            times += list(times[-1] + np.arange(1, len(out + back) + 1) / settings.speed)
            labels += [direction] * len(out + back)
    return _to_cop(settings, session, np.array(states), np.array(times), np.array(labels), rng)


def _walk(
    cell: int,
    q: np.ndarray,
    *,
    next_cell: np.ndarray,
    distance: np.ndarray,
    confidence: float,
    rng: np.random.Generator,
    stop: Callable[[float], bool],
    limit: int,
) -> list[int]:
    """Velocity states visited from ``cell`` taking softmax(confidence·Q) actions until
    ``stop(distance[cell])`` or ``limit`` steps (at least one step)."""
    n_cells = len(next_cell)
    visited = []
    for _ in range(max(limit, 1)):
        prefs = confidence * q[cell]
        probs = np.exp(prefs - prefs.max())
        action = int(rng.choice(len(probs), p=probs / probs.sum()))
        cell = int(next_cell[cell, action])
        visited.append(action * n_cells + cell)
        if stop(float(distance[cell])):
            break
    return visited


def _to_cop(
    settings: PatientSettings,
    session: SessionSettings,
    states: np.ndarray,
    times: np.ndarray,
    labels: np.ndarray,
    rng: np.random.Generator,
) -> Recording:
    """Sample the piecewise-linear path through cell centres at ``sample_rate`` and add sway and noise."""
    b, w, h = settings.bounds, settings.width, settings.height
    x, y, _ = velocity_coords(states, width=w, height=h)
    t = np.arange(0.0, times[-1], 1.0 / settings.sample_rate)
    window = max(int(0.4 * settings.sample_rate), 1)
    out = []
    for cells, lo, hi, n in ((x, b.x_min, b.x_max, w), (y, b.y_min, b.y_max, h)):
        sway = np.convolve(
            rng.normal(size=len(t) + window - 1), np.full(window, 1 / np.sqrt(window)), "valid"
        )
        pos = np.interp(t, times, cells + 0.5) + session.sway * sway + session.noise * rng.normal(size=len(t))
        out.append(np.clip(lo + pos * (hi - lo) / n, lo, hi))
    instruction = labels[np.searchsorted(times, t, side="right") - 1]
    return Recording.build(t=t, x=out[0], y=out[1], bounds=b, instruction=instruction)
