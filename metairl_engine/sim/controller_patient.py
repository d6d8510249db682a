"""A second synthetic patient that is *not* a planner: a feedback controller on the force plate.

numpy only. `simulate_patient` (patient.py) plans on the very velocity grid the learner uses, so a fit on its
recordings is judged on the learner's home ground. This patient moves in continuous space instead: its COP is a
damped point mass pulled toward the instructed target by a spring (PD control) and, once there, back to the
centre; the path is bent by the gradient of an inherent preference map over the plate (a comfortable region
and a valley on the patient's weak side), and it is pushed by motor noise. Nothing here solves a Bellman
equation; the only link to the learner's model is the recorded COP.

The patient's weak side has less reach (its targets lie closer to the centre), and the weaker
(unstimulated) session has less reach everywhere, weaker control and more noise. Recordings carry an
instruction column like `simulate_patient`'s: no instruction while resting, the instructed direction from
the cue to the end of the return.

The inherent preference map (``preference``, one value per grid cell) is what a learned baseline reward
should correlate with on the states a demonstration visits; the map is the same in every velocity channel
(``ideal_reward``), since this patient has no preference per direction of motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from metairl_engine.errors import Issue, check
from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS
from metairl_engine.motion.recording import NO_INSTRUCTION, Bounds, Recording
from metairl_engine.sim.patient import ExperimentSettings


@dataclass(frozen=True)
class ControllerSession:
    """One session's motor control.

    ``reach``: fraction of the nominal target distance aimed at; ``stiffness``: the spring's natural
    frequency ω (rad/s; the damping is critical-ish, 2·0.8·ω); ``noise``: motor noise (normalised plate units
    per s^1.5, white acceleration); ``sensor``: measurement noise std (normalised plate units)."""

    name: str
    reach: float
    stiffness: float
    noise: float
    sensor: float


CONTROLLER_UNSTIMULATED = ControllerSession(
    name="unstimulated", reach=0.7, stiffness=3.0, noise=0.25, sensor=0.01
)
"""Less reach, softer control, more motor noise."""

CONTROLLER_STIMULATED = ControllerSession(
    name="stimulated", reach=1.0, stiffness=4.0, noise=0.12, sensor=0.005
)
"""Full reach, stiffer control, less noise."""


@dataclass(frozen=True)
class ControllerSettings(ExperimentSettings):
    """The controller patient's experiment on top of the shared settings (times in seconds, distances as
    fractions of the plate's half-size)."""

    target: float = 0.7
    """Nominal distance of every instructed target from the centre (fraction of the half-size)."""
    weak_side: str = "left"
    """The direction of the patient's weak side (one of `DIRECTION_NAMES`)."""
    weakness: float = 0.35
    """Fraction of reach lost when moving straight toward the weak side; a direction at angle θ from it
    loses ``weakness · max(cos θ, 0)²`` (neighbouring directions lose half)."""
    preference_gain: float = 0.05
    """How strongly the preference map's gradient pulls the COP (acceleration per unit of gradient, in
    units of the spring's ω²)."""
    pause: float = 1.0
    """Rest at the centre between movements, without instruction."""
    reaction: float = 0.3
    """Delay between the cue (instruction starts) and the movement."""
    hold: float = 0.3
    """Time spent near the target before returning."""
    sessions: tuple[ControllerSession, ...] = (CONTROLLER_UNSTIMULATED, CONTROLLER_STIMULATED)

    def issues(self, pointer: str = "/patient") -> list[Issue]:
        """Unusable settings."""
        out = super().issues(pointer)
        if not 0 < self.target < 1:
            out.append(Issue(f"{pointer}/target", "must be in (0, 1)"))
        if not 0 <= self.weakness < 1:
            out.append(Issue(f"{pointer}/weakness", "must be in [0, 1)"))
        if self.weak_side not in DIRECTION_NAMES:
            out.append(Issue(f"{pointer}/weak_side", f"must be one of {', '.join(DIRECTION_NAMES)}"))
        return out


@dataclass(frozen=True, eq=False)
class ControllerPatient:
    """Simulation output.

    ``preference`` (H·W,) is the inherent preference map on grid cells (``y * width + x``); ``ideal_reward``
    (8·H·W,) the same map in every velocity channel; ``targets`` {session: {direction: (x, y)}} where each
    instruction's target lay (plate units); ``sessions`` {name: Recording} with an instruction column.
    """

    width: int
    height: int
    bounds: Bounds
    weak_side: str
    preference: np.ndarray
    ideal_reward: np.ndarray
    targets: dict[str, dict[str, tuple[float, float]]]
    sessions: dict[str, Recording]


def _unit(direction: str) -> np.ndarray:
    """The unit vector (2,) of an instructed direction."""
    d = DIRECTIONS[DIRECTION_NAMES.index(direction)].astype(np.float64)
    return d / np.hypot(d[0], d[1])


def preference_map(u: np.ndarray, v: np.ndarray, weak_side: str) -> np.ndarray:
    """The inherent preference at normalised plate coordinates u, v ∈ [-1, 1]: a broad comfortable region a
    little forward-right of the centre, minus a valley half-way out on the weak side."""
    weak = 0.6 * _unit(weak_side)
    comfort = np.exp(-((u - 0.15) ** 2 + (v - 0.2) ** 2) / (2 * 0.45**2))
    valley = np.exp(-((u - weak[0]) ** 2 + (v - weak[1]) ** 2) / (2 * 0.35**2))
    return np.asarray(comfort - 0.8 * valley)


def _gradient(u: float, v: float, weak_side: str, eps: float = 1e-4) -> np.ndarray:
    """Central-difference gradient of `preference_map` at one point."""
    p = preference_map(np.array([u + eps, u - eps, u, u]), np.array([v, v, v + eps, v - eps]), weak_side)
    return np.array([p[0] - p[1], p[2] - p[3]]) / (2 * eps)


def side_reach(direction: str, weak_side: str, weakness: float) -> float:
    """Fraction of the nominal reach kept in ``direction`` by a patient weak toward ``weak_side``."""
    cos = float(_unit(direction) @ _unit(weak_side))
    return 1.0 - weakness * max(cos, 0.0) ** 2


def simulate_controller_patient(settings: ControllerSettings = ControllerSettings()) -> ControllerPatient:
    """Record every session (deterministic given ``seed``)."""
    check(settings.issues())
    w, h = settings.width, settings.height
    y, x = np.divmod(np.arange(w * h), w)
    u, v = (x + 0.5) / w * 2 - 1, (y + 0.5) / h * 2 - 1  # cell centres, normalised
    cells = preference_map(u, v, settings.weak_side)
    rng = np.random.default_rng(settings.seed)
    sessions, targets = {}, {}
    for s in settings.sessions:
        sessions[s.name], targets[s.name] = _record(settings, s, rng)
    return ControllerPatient(
        width=w,
        height=h,
        bounds=settings.bounds,
        weak_side=settings.weak_side,
        preference=cells,
        ideal_reward=np.tile(cells, 8),
        targets=targets,
        sessions=sessions,
    )


class _Controller:
    """The COP as a damped point mass under PD control toward a goal, bent by the preference gradient."""

    def __init__(self, settings: ControllerSettings, session: ControllerSession, rng: np.random.Generator):
        self.settings, self.session, self.rng = settings, session, rng
        self.rate = settings.sample_rate
        self.kp, self.kd = session.stiffness**2, 2 * 0.8 * session.stiffness
        self.pos, self.vel = np.zeros(2), np.zeros(2)
        self.xs: list[np.ndarray] = []
        self.labels: list[str] = []

    def step(self, goal: np.ndarray, label: str) -> None:
        """One semi-implicit Euler step of 1 / sample_rate seconds."""
        dt = 1.0 / self.rate
        pull = self.kp * (goal - self.pos) - self.kd * self.vel
        bend = (
            self.settings.preference_gain
            * self.kp
            * _gradient(float(self.pos[0]), float(self.pos[1]), self.settings.weak_side)
        )
        noise = self.session.noise * self.rng.normal(size=2) / np.sqrt(dt)
        self.vel = self.vel + dt * (pull + bend + noise)
        self.pos = np.clip(self.pos + dt * self.vel, -0.98, 0.98)
        self.xs.append(self.pos.copy())
        self.labels.append(label)

    def run(self, seconds: float, goal: np.ndarray, label: str) -> None:
        """Hold ``goal`` for a fixed time."""
        for _ in range(max(round(seconds * self.rate), 1)):
            self.step(goal, label)

    def reach(self, goal: np.ndarray, label: str, *, max_s: float = 3.0) -> None:
        """Move toward ``goal`` until near it and slow (at least 0.3 s, at most ``max_s``)."""
        for k in range(round(max_s * self.rate)):
            self.step(goal, label)
            settled = np.hypot(*self.vel) < 0.15 and np.hypot(*(self.pos - goal)) < 0.1
            if k >= 0.3 * self.rate and settled:
                return


def _record(
    settings: ControllerSettings, session: ControllerSession, rng: np.random.Generator
) -> tuple[Recording, dict[str, tuple[float, float]]]:
    """Rest, cue, out, hold, back, for every repetition of every instruction; then the COP samples."""
    c = _Controller(settings, session, rng)
    origin = np.zeros(2)
    goals: dict[str, tuple[float, float]] = {}
    for direction in settings.directions:
        reach = settings.target * session.reach * side_reach(direction, settings.weak_side, settings.weakness)
        goal = reach * _unit(direction)
        goals[direction] = _to_plate(settings.bounds, goal)
        for _ in range(settings.repetitions):
            c.run(settings.pause, origin, NO_INSTRUCTION)
            c.run(settings.reaction, origin, direction)
            c.reach(goal, direction)
            c.run(settings.hold, goal, direction)
            c.reach(origin, direction)
    c.run(settings.pause, origin, NO_INSTRUCTION)

    xy = np.array(c.xs) + session.sensor * rng.normal(size=(len(c.xs), 2))
    b = settings.bounds
    cx, cy = b.centre
    half_x, half_y = (b.x_max - b.x_min) / 2, (b.y_max - b.y_min) / 2
    rec = Recording.build(
        t=np.arange(len(xy)) / settings.sample_rate,
        x=np.clip(cx + xy[:, 0] * half_x, b.x_min, b.x_max),
        y=np.clip(cy + xy[:, 1] * half_y, b.y_min, b.y_max),
        bounds=b,
        instruction=np.array(c.labels),
    )
    return rec, goals


def _to_plate(b: Bounds, p: np.ndarray) -> tuple[float, float]:
    """Normalised plate coordinates → plate units."""
    cx, cy = b.centre
    return float(cx + p[0] * (b.x_max - b.x_min) / 2), float(cy + p[1] * (b.y_max - b.y_min) / 2)
