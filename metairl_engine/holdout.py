"""Hold out a seeded fraction of each task's demonstrated steps to pick the stopping step by likelihood.

Why: the training loss is no stopping signal (a few demonstrations are overfit and the reward drifts
after an early peak); the held-out negative log-likelihood needs no knowledge of the true reward.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from metairl_engine.demos import Trajectory, state_action_pairs


@dataclass(frozen=True)
class Steps:
    """Demonstrated steps of several tasks, flattened: ``tasks``, ``states``, ``actions`` all (N,) int64."""

    tasks: np.ndarray
    states: np.ndarray
    actions: np.ndarray

    def __len__(self) -> int:
        return int(self.tasks.shape[0])


def split_steps(
    demonstrations: Sequence[Sequence[Trajectory]], *, fraction: float, seed: int, fold: int = 0
) -> tuple[Steps, Steps]:
    """(train, held-out) steps: m = ⌊fraction·n⌋ random steps of each task's n are held out, ≥ 1 kept.

    Fold k holds out positions k·m … (k+1)·m − 1 (mod n) of one seeded permutation of each task's steps,
    so the folds 0 … ⌈1/fraction⌉ − 1 of one seed hold out disjoint steps (k-fold cross-fitting).
    """
    rng = np.random.default_rng(seed)
    parts: dict[bool, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {True: [], False: []}
    for t, trajectories in enumerate(demonstrations):
        states, actions = state_action_pairs(trajectories)
        n = len(actions)
        held = np.zeros(n, dtype=bool)
        m = min(int(fraction * n), n - 1)
        held[rng.permutation(n)[(fold * m + np.arange(m)) % n]] = True
        for is_held in (False, True):
            keep = held == is_held
            parts[is_held].append((np.full(int(keep.sum()), t, dtype=np.int64), states[keep], actions[keep]))

    def stack(rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> Steps:
        return Steps(*(np.concatenate([r[k] for r in rows]) for k in range(3)))

    return stack(parts[False]), stack(parts[True])
