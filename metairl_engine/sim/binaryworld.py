"""Wulfmeier, Ondrúška & Posner (2015)'s binaryworld: a reward no linear function of the features gives.

An N×N grid of cells, each blue or red at random (p = 0.5), with objectworld's 5 actions and wind. A
state's features are the colours (1 blue, 0 red) of the 9 cells of its 3×3 neighbourhood, row by row
(cells off the grid count as red); its true reward is +1 where exactly 4 of the 9 are blue, −1 where
exactly 5 are, else 0.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from metairl_engine.grids import grid_mdp
from metairl_engine.sim.benchmark import RewardWorld, wind_to_slip
from metairl_engine.sim.objectworld import N_ACTIONS


def binaryworld_features(blue: np.ndarray) -> np.ndarray:
    """The 3×3 neighbourhood colours (S, 9) float32 of a (size, size) boolean grid ``blue[y, x]``."""
    size = blue.shape[0]
    padded = np.pad(blue, 1, constant_values=False)
    cols = [
        padded[1 + dy : 1 + dy + size, 1 + dx : 1 + dx + size].reshape(-1)
        for dy in (-1, 0, 1)
        for dx in (-1, 0, 1)
    ]
    return np.stack(cols, axis=1).astype(np.float32)


def binaryworld_reward(features: np.ndarray) -> np.ndarray:
    """+1 where exactly 4 of a state's 9 neighbourhood cells are blue, −1 where exactly 5, else 0 (S,)."""
    blue = features.sum(axis=1)
    return np.where(blue == 4, 1.0, np.where(blue == 5, -1.0, 0.0)).astype(np.float32)


def make_binaryworld(
    *, seed: int, size: int = 32, p_blue: float = 0.5, wind: float = 0.3, gamma: float = 0.9
) -> RewardWorld:
    """A random binaryworld."""
    blue = np.random.default_rng(seed).random((size, size)) < p_blue
    features = binaryworld_features(blue)
    mdp = grid_mdp(
        width=size, height=size, moves=4, stay=True, gamma=gamma, slip=wind_to_slip(wind, N_ACTIONS)
    )
    return RewardWorld(size=size, reward=binaryworld_reward(features), mdp=replace(mdp, features=features))
