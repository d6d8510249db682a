"""Tiny MDPs and demonstrations shared by the engine tests (one place, not copied per file)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from metairl_engine import MDP, Trajectory
from metairl_engine.grids import grid_mdp
from metairl_engine.planning import transition_matrix, value_iteration
from metairl_engine.results import TaskData

# Test tensors are tiny and the machine's cores are shared: one thread is fastest and avoids stalls.
torch.set_num_threads(1)


def small_grid(*, size: int = 5, gamma: float = 0.9) -> MDP:
    """A size×size grid with 4 moves and stay, normalised (x, y) features, deterministic."""
    return grid_mdp(width=size, height=size, moves=4, stay=True, gamma=gamma)


def as_sparse(mdp: MDP) -> MDP:
    """The same MDP with its deterministic table rewritten as sparse (s, a, next, p=1) triples."""
    assert mdp.next_state is not None
    s, a = np.divmod(np.arange(mdp.n_states * mdp.n_actions), mdp.n_actions)
    return MDP.build(
        gamma=mdp.gamma,
        n_states=mdp.n_states,
        n_actions=mdp.n_actions,
        features=mdp.features,
        s=s,
        a=a,
        next=mdp.next_state.reshape(-1),
        p=np.ones(len(s)),
        layout=mdp.layout,
    )


def soft_demos(
    mdp: MDP, reward: np.ndarray, *, starts: np.ndarray, length: int, seed: int, confidence: float = 1.0
) -> list[Trajectory]:
    """Trajectories of the soft-optimal policy of ``reward`` (one per start state, ``length`` steps)."""
    assert mdp.next_state is not None
    rng = np.random.default_rng(seed)
    policy = value_iteration(transition_matrix(mdp), reward, gamma=mdp.gamma, confidence=confidence).policy
    out = []
    for start in starts:
        states, actions = [int(start)], []
        for _ in range(length):
            a = int(rng.choice(mdp.n_actions, p=policy[states[-1]]))
            actions.append(a)
            states.append(int(mdp.next_state[states[-1], a]))
        out.append(Trajectory.of(states, actions))
    return out


def task(mdp: MDP, trajectories: list[Trajectory]) -> TaskData:
    """Shorthand for a named TaskData."""
    return TaskData(mdp=mdp, trajectories=trajectories, name="t")


def goal_tasks_with_features(features: np.ndarray) -> list[TaskData]:
    """Two goal tasks (goals 18 and 0) on a seeded 5×5 grid whose state features are ``features`` (25, F)."""
    mdp = replace(small_grid(size=5), features=features)
    out = []
    for goal in (18, 0):
        reward = np.zeros(25)
        reward[goal] = 1.0
        demos = soft_demos(mdp, reward, starts=np.arange(0, 25, 4), length=5, seed=goal, confidence=5.0)
        out.append(task(mdp, demos))
    return out
