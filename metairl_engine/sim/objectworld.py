"""Levine, Popović & Koltun (2011)'s objectworld: objects of coloured rings on a windy grid.

An N×N grid with 5 actions (E, N, W, S, stay; `grids.grid_moves`); with probability ``wind`` the action
is replaced by a uniformly random one of the 5 (moves off the grid stay). Objects sit on distinct random
cells, each with an outer and an inner colour out of C. The true reward of a cell is +1 if it lies within
distance 3 of an object of outer colour 0 and within 2 of one of outer colour 1, −1 if within 3 of outer
colour 0 only, else 0. As in the common Python port (Alger's ``irl/mdp/objectworld.py``) the reward's
radii are Manhattan distances |dx| + |dy| (inclusive) and the features are Euclidean distances: continuous
features are the distance to the nearest object of each inner colour, then of each outer colour (2C
columns); discrete ones the indicators "distance < d" for d = 1 … N of each of those (2C·N columns).
Defaults follow the MATLAB IRL toolkit's ``objectworldbuild.m`` (n = 32, an object on 5 % of the cells,
C = 2, γ = 0.9).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from metairl_engine.grids import grid_mdp
from metairl_engine.sim.benchmark import RewardWorld, wind_to_slip

N_ACTIONS = 5
"""E, N, W, S, stay."""


@dataclass(frozen=True)
class Objects:
    """Objects of a world: cells ``xy`` (n, 2) int, ``inner`` and ``outer`` colours (n,) int."""

    xy: np.ndarray
    inner: np.ndarray
    outer: np.ndarray


def objectworld_reward(size: int, objects: Objects) -> np.ndarray:
    """The published rule per cell (S,) float32: +1 near outer colours 0 (≤ 3) and 1 (≤ 2), −1 near 0 only."""
    ys, xs = np.divmod(np.arange(size * size), size)
    manhattan = np.abs(xs[:, None] - objects.xy[None, :, 0]) + np.abs(ys[:, None] - objects.xy[None, :, 1])
    near0 = ((manhattan <= 3) & (objects.outer[None, :] == 0)).any(axis=1)
    near1 = ((manhattan <= 2) & (objects.outer[None, :] == 1)).any(axis=1)
    return np.where(near0 & near1, 1.0, np.where(near0, -1.0, 0.0)).astype(np.float32)


def nearest_by_colour(
    distance: np.ndarray, inner: np.ndarray, outer: np.ndarray, *, n_colours: int, far: float
) -> np.ndarray:
    """Per state, the distance (S, 2C) to the nearest object of each inner, then each outer colour, from each
    state's ``distance`` (S, n) to the n objects; ``far`` where no object has that colour."""
    columns = [
        np.where(colours[None, :] == c, distance, far).min(axis=1, initial=far)
        for colours in (inner, outer)
        for c in range(n_colours)
    ]
    return np.stack(columns, axis=1)


def objectworld_features(size: int, objects: Objects, *, n_colours: int, discrete: bool) -> np.ndarray:
    """Euclidean distance to the nearest object of each inner, then each outer colour (S, 2C), or their
    indicators "distance < d", d = 1 … size, per column (S, 2C·size); float32. No object of a colour: the
    grid's diagonal."""
    ys, xs = np.divmod(np.arange(size * size), size)
    dist = np.hypot(xs[:, None] - objects.xy[None, :, 0], ys[:, None] - objects.xy[None, :, 1])
    nearest = nearest_by_colour(
        dist, objects.inner, objects.outer, n_colours=n_colours, far=np.hypot(size, size)
    )
    if not discrete:
        return nearest.astype(np.float32)
    steps = np.arange(1, size + 1)
    return (nearest[:, :, None] < steps).reshape(size * size, -1).astype(np.float32)


def make_objectworld(
    *,
    seed: int,
    size: int = 32,
    n_objects: int | None = None,
    n_colours: int = 2,
    wind: float = 0.3,
    gamma: float = 0.9,
    discrete: bool = False,
) -> tuple[RewardWorld, Objects]:
    """A random objectworld (``n_objects`` default: 5 % of the cells) and its objects."""
    rng = np.random.default_rng(seed)
    count = max(2, round(0.05 * size * size)) if n_objects is None else n_objects
    cells = rng.choice(size * size, size=count, replace=False)
    ys, xs = np.divmod(cells, size)
    objects = Objects(
        xy=np.stack([xs, ys], axis=1),
        inner=rng.integers(n_colours, size=count),
        outer=rng.integers(n_colours, size=count),
    )
    mdp = grid_mdp(
        width=size, height=size, moves=4, stay=True, gamma=gamma, slip=wind_to_slip(wind, N_ACTIONS)
    )
    features = objectworld_features(size, objects, n_colours=n_colours, discrete=discrete)
    world = RewardWorld(
        size=size, reward=objectworld_reward(size, objects), mdp=replace(mdp, features=features)
    )
    return world, objects
