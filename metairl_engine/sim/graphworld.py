"""Objectworld's rule on a random geometric graph: a world with no grid and no layout.

States are ``n`` random points in the unit square; action 0 stays and action j moves to the state's j-th
nearest other point (deterministic). Objects sit on 5 % of the points, each with an inner and an outer
colour out of C, as in Levine, Popović & Koltun (2011)'s objectworld (`sim.objectworld`); the grid's
Manhattan radii become hops of the graph (moves either way round): +1 within 3 hops of an object of outer
colour 0 and within 2 of one of outer colour 1, −1 within 3 of outer colour 0 only, else 0. The features are
Euclidean distances to the nearest object of each inner, then each outer colour, in units of the points'
mean spacing 1/√n (a grid cell when n = N²). What it tests: an MDP uploaded with features and without a
layout, whose task networks see coordinates recovered from the transition graph (`coordinates`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import shortest_path
from scipy.spatial import cKDTree

from metairl_engine.mdp import MDP
from metairl_engine.sim.benchmark import RewardWorld


def hops_between(next_state: np.ndarray) -> np.ndarray:
    """Fewest moves (S, S) between states over the actions of ``next_state`` (S, A), either way round."""
    n_states = next_state.shape[0]
    rows = np.repeat(np.arange(n_states), next_state.shape[1])
    graph = sp.csr_matrix((np.ones(rows.size), (rows, next_state.reshape(-1))), shape=(n_states, n_states))
    return np.asarray(shortest_path(graph + graph.T, unweighted=True, directed=False))


def graphworld_reward(hops: np.ndarray, objects: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """Objectworld's rule per state (S,) float32, on ``hops`` (S, S), the objects' states and their outer
    colours: +1 within 3 hops of outer colour 0 and 2 of outer colour 1, −1 within 3 of colour 0 only."""
    to_objects = hops[:, objects]
    near0 = ((to_objects <= 3) & (outer[None, :] == 0)).any(axis=1)
    near1 = ((to_objects <= 2) & (outer[None, :] == 1)).any(axis=1)
    return np.where(near0 & near1, 1.0, np.where(near0, -1.0, 0.0)).astype(np.float32)


def make_graphworld(
    *, seed: int, n_states: int = 1024, n_neighbours: int = 4, n_colours: int = 2, gamma: float = 0.9
) -> RewardWorld:
    """A random graph objectworld: ``n_states`` points, stay or move to one of the ``n_neighbours`` nearest."""
    rng = np.random.default_rng(seed)
    points = rng.random((n_states, 2))
    _, nearest = cKDTree(points).query(points, n_neighbours + 1)  # column 0: the point itself (stay)
    next_state = nearest.astype(np.int32)
    count = max(2, round(0.05 * n_states))
    objects = rng.choice(n_states, size=count, replace=False)
    inner, outer = rng.integers(n_colours, size=count), rng.integers(n_colours, size=count)
    distance = np.linalg.norm(points[:, None] - points[None, objects], axis=2) * np.sqrt(n_states)
    far = np.sqrt(2 * n_states)  # the unit square's diagonal in these units
    features = np.stack(
        [
            np.where(colours[None, :] == c, distance, far).min(axis=1, initial=far)
            for colours in (inner, outer)
            for c in range(n_colours)
        ],
        axis=1,
    ).astype(np.float32)
    mdp = MDP.build(gamma=gamma, features=features, next_state=next_state)
    reward = graphworld_reward(hops_between(next_state), objects, outer)
    return RewardWorld(size=round(np.sqrt(n_states)), reward=reward, mdp=mdp)
