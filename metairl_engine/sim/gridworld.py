"""The gridworld of Levine's IRL toolkit (`gridworldbuild.m`, after Abbeel & Ng 2004): a reward constant on
macro cells, seen through features that say only where a state is.

An N×N grid cut into b×b macro cells, each with its own reward U⁸·R_SCALE (U uniform on [0, 1): most cells
near 0, a few large); objectworld's 5 actions, the chosen one taken with probability ``determinism`` and
each of the other four with a quarter of the rest. A state's features are the toolkit's split table: for
k = 1 … N − 1, whether x ≥ k, then whether y ≥ k (2(N − 1) indicator columns, a thermometer code of the
place), so the reward is a function of the features that no linear one of them need match.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from metairl_engine.grids import grid_mdp
from metairl_engine.sim.benchmark import RewardWorld

R_SCALE = 100.0
"""The toolkit's reward scale: a macro cell's reward is U⁸·R_SCALE."""


def split_table(size: int) -> np.ndarray:
    """The toolkit's features (S, 2(size − 1)) float32, state = y·size + x: [x ≥ k for k = 1 … size − 1]
    then [y ≥ k for k = 1 … size − 1]."""
    y, x = np.divmod(np.arange(size * size), size)
    k = np.arange(1, size)
    return np.concatenate([x[:, None] >= k, y[:, None] >= k], axis=1).astype(np.float32)


def macro_cell_reward(macro: np.ndarray, block: int) -> np.ndarray:
    """Each macro cell's reward on its block×block states (S,) float32, from ``macro[yc, xc]``."""
    return np.kron(macro, np.ones((block, block))).reshape(-1).astype(np.float32)


def make_gridworld(
    *,
    seed: int,
    size: int = 32,
    block: int = 4,
    determinism: float = 0.7,
    gamma: float = 0.9,
    scale: float = R_SCALE,
) -> RewardWorld:
    """A random toolkit gridworld; ``scale`` replaces R_SCALE (a goal task's bonus is in the world's units)."""
    if size % block:
        raise ValueError(f"size {size} is not a whole number of macro cells of {block}")
    macro = np.random.default_rng(seed).random((size // block, size // block)) ** 8 * scale
    mdp = grid_mdp(width=size, height=size, moves=4, stay=True, gamma=gamma, slip=1.0 - determinism)
    return RewardWorld(
        size=size, reward=macro_cell_reward(macro, block), mdp=replace(mdp, features=split_table(size))
    )
