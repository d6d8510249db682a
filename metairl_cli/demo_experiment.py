"""The terrain experiment of `metairl demo` (paper §IV-A, Fig. 2) as data: settings, worlds, the job plan, outcomes.

No HTTP here: `make_experiment` generates seeded worlds and goal tasks with `metairl_engine.sim.terrain`
(numpy only), `plan_jobs` lists one job per (world, task count, sharing loss), and `JobOutcome` holds
what came back, scored client-side with `goal_excluded_pearson`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, get_args

import numpy as np

from metairl_engine.config import Sharing
from metairl_engine.metrics import pearson
from metairl_engine.sim.terrain import SimTask, World, make_tasks, make_world

TASK_SEED_OFFSET = 1000
"""World i's tasks are seeded ``TASK_SEED_OFFSET + seed + i`` (benchmarks/accuracy.py's scheme)."""

SHARING_LOSSES: tuple[str, ...] = get_args(Sharing)
"""Every reward-sharing loss of the paper: none, l2, huber, std, entropy."""


@dataclass(frozen=True, kw_only=True)
class DemoSettings:
    """Size of the experiment: worlds × goal tasks × demonstrations, the task counts and losses to fit."""

    n_worlds: int
    size: int
    n_hills: int
    n_demos: int
    task_counts: tuple[int, ...]
    losses: tuple[str, ...]
    max_steps: int
    seed: int = 0

    @property
    def n_tasks(self) -> int:
        """Goal tasks generated per world: enough for the largest task count (smaller counts use a prefix)."""
        return max(self.task_counts)

    def job_config(self, loss: str) -> dict[str, Any]:
        """The `config` of a job fitting with sharing loss ``loss`` (docs/api.md, "Jobs" contract names)."""
        return {"sharing": loss, "seed": self.seed, "max_steps": self.max_steps}


QUICK = DemoSettings(
    n_worlds=2,
    size=10,
    n_hills=4,
    n_demos=5,
    task_counts=(1, 2, 4),
    losses=("none", "l2", "huber"),
    max_steps=200,
)
"""`--quick`: about a minute on two cores."""

FULL = DemoSettings(
    n_worlds=10,
    size=16,
    n_hills=6,
    n_demos=10,
    task_counts=(1, 2, 4, 8, 16),
    losses=SHARING_LOSSES,
    max_steps=1000,
)
"""The paper's set-up and benchmarks/accuracy.py's worlds: ten 16×16 worlds of 6 hills, 16 goal tasks with ten
demonstrations each, all five losses, the default max_steps."""


@dataclass(frozen=True)
class SimWorld:
    """One generated world (index in the experiment) and its goal tasks with demonstrations and true rewards."""

    index: int
    world: World
    tasks: list[SimTask]


def make_experiment(settings: DemoSettings) -> list[SimWorld]:
    """``n_worlds`` seeded terrains, each with ``n_tasks`` distinct-goal tasks of ``n_demos`` demonstrations.

    World i is seeded ``seed + i`` and its tasks ``1000 + seed + i``, as in benchmarks/accuracy.py: with
    seed 0 the full demo fits the benchmark's worlds, tasks and demonstrations.
    """
    worlds = []
    for i in range(settings.n_worlds):
        world = make_world(size=settings.size, n_hills=settings.n_hills, seed=settings.seed + i)
        tasks = make_tasks(
            world,
            n_tasks=settings.n_tasks,
            n_demos=settings.n_demos,
            seed=TASK_SEED_OFFSET + settings.seed + i,
        )
        worlds.append(SimWorld(index=i, world=world, tasks=tasks))
    return worlds


@dataclass(frozen=True)
class JobPlan:
    """One job of the experiment: fit the first ``n_tasks`` tasks of world ``world`` with sharing ``loss``."""

    world: int
    loss: str
    n_tasks: int

    def describe(self) -> str:
        """``world 0, huber, 4 tasks``: the job in words, for progress bars and messages."""
        return f"world {self.world}, {self.loss}, {tasks_label(self.n_tasks)}"


def plan_jobs(settings: DemoSettings) -> list[JobPlan]:
    """Every (world, task count, loss) job, world by world so early results cover every loss."""
    return [
        JobPlan(world=w, loss=loss, n_tasks=k)
        for w in range(settings.n_worlds)
        for k in settings.task_counts
        for loss in settings.losses
    ]


@dataclass(frozen=True)
class JobOutcome:
    """A finished job: its status and, when it succeeded, the downloaded rewards and their scores.

    ``rewards`` is (n_tasks, S) in the plan's task order, ``pearsons`` each task reward's Pearson with its
    true reward (goal excluded), ``baseline_pearson`` the baseline's Pearson with the world's −cost.
    """

    plan: JobPlan
    job_id: str
    status: str
    error: str | None = None
    task_ids: tuple[str, ...] = ()
    reward_ids: tuple[str, ...] = ()
    baseline_reward_id: str | None = None
    rewards: np.ndarray | None = None
    baseline: np.ndarray | None = None
    pearsons: tuple[float, ...] = ()
    baseline_pearson: float | None = None

    @classmethod
    def scored(
        cls,
        sim: SimWorld,
        plan: JobPlan,
        *,
        job_id: str,
        task_ids: tuple[str, ...],
        reward_ids: tuple[str, ...],
        baseline_reward_id: str,
        rewards: np.ndarray,
        baseline: np.ndarray,
    ) -> JobOutcome:
        """A succeeded job's outcome, its downloaded rewards scored against the simulation's truth."""
        tasks = sim.tasks[: plan.n_tasks]
        pearsons = tuple(
            goal_excluded_pearson(r, t.true_reward, goal=t.goal) for r, t in zip(rewards, tasks, strict=True)
        )
        return cls(
            plan=plan,
            job_id=job_id,
            status="succeeded",
            task_ids=task_ids,
            reward_ids=reward_ids,
            baseline_reward_id=baseline_reward_id,
            rewards=rewards,
            baseline=baseline,
            pearsons=pearsons,
            baseline_pearson=pearson(baseline, -sim.world.cost),
        )

    @property
    def succeeded(self) -> bool:
        """True when the job succeeded and its rewards were downloaded."""
        return self.status == "succeeded" and self.rewards is not None

    def to_json(self) -> dict[str, Any]:
        """The outcome for results.json (ids and scores; the reward values stay downloadable by id)."""
        return {
            "world": self.plan.world,
            "loss": self.plan.loss,
            "n_tasks": self.plan.n_tasks,
            "job_id": self.job_id,
            "status": self.status,
            "error": self.error,
            "task_ids": list(self.task_ids),
            "reward_ids": list(self.reward_ids),
            "baseline_reward_id": self.baseline_reward_id,
            "pearson": list(self.pearsons),
            "baseline_pearson": self.baseline_pearson,
        }


def tasks_label(n: int) -> str:
    """``1 task``, ``4 tasks``."""
    return f"{n} task{'' if n == 1 else 's'}"


def goal_excluded_pearson(learned: np.ndarray, truth: np.ndarray, *, goal: int) -> float:
    """Pearson correlation of a learned and a true reward over every state but the goal (paper's accuracy).

    The goal's bonus would otherwise dominate the correlation; 0.0 when either side is constant.
    """
    mask = np.ones(len(truth), dtype=bool)
    mask[goal] = False
    return pearson(learned, truth, mask=mask)
