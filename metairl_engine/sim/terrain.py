"""The paper's path-planning experiment (§IV-A): hilly terrains, goal tasks and a Boltzmann-rational demonstrator.

A world is a size×size grid (8 compass moves + stay) whose cost is a sum of hills, each a peak decaying
exponentially with distance. Task i's true reward is −cost plus a bonus at its goal state; the demonstrator
follows the soft-optimal policy of that reward (soft value iteration) from random starts until it reaches
the goal or a step cap. numpy and scipy only, seeded: the demo CLI and the service tests generate data with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from metairl_engine.demos import Trajectory
from metairl_engine.grids import grid_mdp
from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix, value_iteration


@dataclass(frozen=True)
class World:
    """One terrain: ``cost`` (S,) ≥ 0 over the size×size grid ``mdp`` (state = y·size + x)."""

    size: int
    cost: np.ndarray
    mdp: MDP


@dataclass(frozen=True)
class SimTask:
    """A simulated task: its ``goal`` state, ``true_reward`` (S,) = −cost + bonus·[s = goal], demonstrations."""

    name: str
    goal: int
    true_reward: np.ndarray
    trajectories: list[Trajectory]


def make_world(
    *,
    size: int = 16,
    n_hills: int = 6,
    seed: int,
    gamma: float = 0.9,
    height_range: tuple[float, float] = (0.5, 2.0),
    decay_range: tuple[float, float] = (1.5, 4.0),
) -> World:
    """A random terrain: ``n_hills`` peaks of height in ``height_range``, cost ∝ exp(−distance / decay)."""
    rng = np.random.default_rng(seed)
    ys, xs = np.divmod(np.arange(size * size), size)
    centres = rng.uniform(0, size - 1, size=(n_hills, 2))
    heights = rng.uniform(*height_range, size=n_hills)
    decays = rng.uniform(*decay_range, size=n_hills)
    dist = np.hypot(xs[None, :] - centres[:, :1], ys[None, :] - centres[:, 1:])  # (hills, S)
    cost = (heights[:, None] * np.exp(-dist / decays[:, None])).sum(axis=0)
    mdp = grid_mdp(width=size, height=size, moves=8, stay=True, gamma=gamma)
    return World(size=size, cost=cost.astype(np.float32), mdp=mdp)


def make_tasks(
    world: World,
    *,
    n_tasks: int,
    n_demos: int,
    seed: int,
    goal_bonus: float = 3.0,
    rationality: float = 2.0,
    max_length: int | None = None,
) -> list[SimTask]:
    """``n_tasks`` tasks with distinct random goals, each with ``n_demos`` soft-optimal demonstrations.

    The demonstrator picks actions from softmax(rationality·Q_soft) of the true reward; a trajectory
    starts at a random non-goal state and stops at the goal or after ``max_length`` (default 3·size) steps.
    """
    return tasks_with_goals(
        world.mdp,
        -world.cost.astype(np.float64),
        size=world.size,
        n_tasks=n_tasks,
        n_demos=n_demos,
        seed=seed,
        goal_bonus=goal_bonus,
        rationality=rationality,
        max_length=max_length,
    )


def tasks_with_goals(
    mdp: MDP,
    base_reward: np.ndarray,
    *,
    size: int,
    n_tasks: int,
    n_demos: int,
    seed: int,
    goal_bonus: float,
    rationality: float,
    max_length: int | None,
) -> list[SimTask]:
    """``n_tasks`` tasks on one world of ``size``×``size`` cells: task i's true reward is ``base_reward`` plus
    ``goal_bonus`` at its own random goal, demonstrated by softmax(rationality·Q_soft) from a random non-goal
    start to the goal or for ``max_length`` (default 3·size) steps."""
    rng = np.random.default_rng(seed)
    goals = rng.choice(mdp.n_states, size=n_tasks, replace=n_tasks > mdp.n_states)
    p = transition_matrix(mdp)
    cap = 3 * size if max_length is None else max_length
    tasks = []
    for goal in goals:
        reward = np.array(base_reward, dtype=np.float64)
        reward[goal] += goal_bonus
        policy = demonstrator_policy(p, reward, gamma=mdp.gamma, rationality=rationality)
        trajectories = [
            rollout(mdp, p, policy, goal=int(goal), max_length=cap, rng=rng) for _ in range(n_demos)
        ]
        tasks.append(SimTask(f"goal {goal}", int(goal), reward.astype(np.float32), trajectories))
    return tasks


def demonstrator_policy(
    p: sp.csr_matrix, reward: np.ndarray, *, gamma: float, rationality: float
) -> np.ndarray:
    """The demonstrator's policy (S, A) for ``reward`` under transitions ``p``: softmax(rationality·Q_soft),
    Boltzmann-rational; with ``rationality`` infinite, the optimal policy itself (greedy in Q*, ties shared), as
    the published objectworld toolkits demonstrate it."""
    if math.isinf(rationality):
        return value_iteration(p, reward, gamma=gamma, backup="max").policy
    return value_iteration(p, reward, gamma=gamma, backup="soft", confidence=rationality).policy


def rollout(
    mdp: MDP,
    p: sp.csr_matrix,
    policy: np.ndarray,
    *,
    goal: int | None,
    max_length: int,
    rng: np.random.Generator,
) -> Trajectory:
    """Sample one trajectory (with its final state) of ``policy`` from a uniformly random start: with a
    ``goal``, a non-goal start, until the goal or ``max_length`` steps; without, ``max_length`` steps.

    ``p`` is the MDP's `transition_matrix`: a stochastic MDP's next state is drawn from row s·A + a (a
    deterministic one's is looked up, drawing nothing, so its demonstrations do not depend on ``p``).
    """
    if goal is None:
        state = int(rng.integers(mdp.n_states))
    else:
        state = int(rng.integers(mdp.n_states - 1))
        state += state >= goal
    states, actions = [state], list[int]()
    while state != goal and len(actions) < max_length:
        action = int(rng.choice(mdp.n_actions, p=policy[state]))
        if mdp.next_state is not None:
            state = int(mdp.next_state[state, action])
        else:
            index = state * mdp.n_actions + action
            row = slice(p.indptr[index], p.indptr[index + 1])
            chance = p.data[row]  # float32 probabilities: renormalised to numpy's float64 tolerance
            state = int(rng.choice(p.indices[row], p=chance / chance.sum()))
        states.append(state)
        actions.append(action)
    return Trajectory.of(states, actions)
