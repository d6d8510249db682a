"""What the benchmark gridworld families share: a world with a true state reward, and its demonstrators.

A family (objectworld, binaryworld) builds a `RewardWorld`; `single_task` gives it the published
benchmark's demonstrations (short paths of the demonstrator from uniform starts), `goal_tasks` its
multi-task form (the meta case): T tasks whose reward is the world's plus a bonus at a random goal cell.
Both demonstrators are Boltzmann-rational like the terrain's: softmax(rationality·Q_soft) of the task's
true reward, or with an infinite rationality the optimal policy (`terrain.demonstrator_policy`). numpy and scipy only, seeded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix
from metairl_engine.sim.terrain import SimTask, demonstrator_policy, rollout, tasks_with_goals


@dataclass(frozen=True)
class RewardWorld:
    """A size×size grid ``mdp`` (state = y·size + x) with its true state reward ``reward`` (S,)."""

    size: int
    reward: np.ndarray
    mdp: MDP


def wind_to_slip(wind: float, n_actions: int) -> float:
    """`grid_mdp`'s slip (chance of another action) for the published wind (chance of a uniformly random
    action, possibly the chosen one): slip = wind·(A − 1)/A."""
    return wind * (n_actions - 1) / n_actions


def single_task(
    world: RewardWorld, *, n_demos: int, seed: int, length: int = 8, rationality: float = 2.0
) -> SimTask:
    """The world's own reward as one task, with ``n_demos`` demonstrations of ``length`` steps from uniform
    random starts (the published objectworld protocol: paths of 8 steps)."""
    rng = np.random.default_rng(seed)
    p = transition_matrix(world.mdp)
    policy = demonstrator_policy(p, world.reward, gamma=world.mdp.gamma, rationality=rationality)
    demos = [rollout(world.mdp, p, policy, goal=None, max_length=length, rng=rng) for _ in range(n_demos)]
    return SimTask(name="world", goal=-1, true_reward=world.reward.astype(np.float32), trajectories=demos)


def goal_tasks(
    world: RewardWorld,
    *,
    n_tasks: int,
    n_demos: int,
    seed: int,
    goal_bonus: float = 3.0,
    rationality: float = 2.0,
    max_length: int | None = None,
) -> list[SimTask]:
    """``n_tasks`` tasks on one world: task i's reward is the world's plus ``goal_bonus`` at its own random
    goal cell; its demonstrations start at a random non-goal cell and stop at the goal or after
    ``max_length`` (default 3·size) steps."""
    return tasks_with_goals(
        world.mdp,
        world.reward,
        size=world.size,
        n_tasks=n_tasks,
        n_demos=n_demos,
        seed=seed,
        goal_bonus=goal_bonus,
        rationality=rationality,
        max_length=max_length,
    )
