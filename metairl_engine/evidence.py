"""Where the demonstrations give evidence about a reward: per state, visited, next to a visit, or neither.

numpy and scipy only. A demonstrated step from s constrains the reward through Q(s, ·), which reads f on
every successor of s (paper eq. 6), so a state one move from a visit is constrained too, if more weakly;
anywhere else the reward is what the networks extrapolate. Stored by the worker beside each reward
(``?quantity=evidence``) and read with its spread across the ensemble's members (`FitResult.reward_spread`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from metairl_engine.demos import Trajectory
from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix
from metairl_engine.results import TaskData

VISITED = 1.0
"""Evidence of a state a demonstration passes through."""

NEXT_TO_VISITED = 0.5
"""Evidence of a state one move (any action) from a visited state, not visited itself."""


def evidence(mdp: MDP, trajectories: Sequence[Trajectory]) -> np.ndarray:
    """Per state (float32, (S,)): `VISITED` where ``trajectories`` pass, `NEXT_TO_VISITED` one move from such
    a state, 0 elsewhere."""
    out = np.zeros(mdp.n_states, dtype=np.float32)
    if not trajectories:
        return out
    visited = np.unique(np.concatenate([np.asarray(t.states, dtype=np.int64) for t in trajectories]))
    if mdp.next_state is not None:
        reached = mdp.next_state[visited].reshape(-1)
    else:
        rows = (visited[:, None] * mdp.n_actions + np.arange(mdp.n_actions)).reshape(-1)
        reached = transition_matrix(mdp)[rows].indices
    out[reached] = NEXT_TO_VISITED
    out[visited] = VISITED
    return out


def tasks_evidence(tasks: Sequence[TaskData]) -> tuple[np.ndarray, list[np.ndarray]]:
    """The evidence of the baseline (per state, the most any task's demonstrations give: the baseline is
    shared by all tasks) and of each task (its own demonstrations)."""
    per_task = [evidence(t.mdp, t.trajectories) for t in tasks]
    return np.max(per_task, axis=0), per_task
