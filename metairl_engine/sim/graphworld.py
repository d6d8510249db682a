"""Objectworld's rule on a random geometric graph: a world with no grid and no layout.

States are ``n`` random points in the unit square; action 0 stays and action j moves to the state's j-th
nearest other point (deterministic; with ``wind``, objectworld's uniformly random action may replace the
chosen one). Objects sit on 5 % of the points, each with an inner and an outer colour out of C, as in Levine,
Popović & Koltun (2011)'s objectworld (`sim.objectworld`); the grid's Manhattan radii become hops of the graph
(moves either way round): +1 within 3 hops of an object of outer colour 0 and within 2 of one of outer colour
1, −1 within 3 of outer colour 0 only, else 0. The features are Euclidean distances to the nearest object of
each inner, then each outer colour, in units of the points' mean spacing 1/√n (a grid cell when n = N²). What
it tests: an MDP uploaded with features and without a layout, whose task networks see coordinates recovered
from the transition graph (`coordinates`).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse.csgraph import shortest_path
from scipy.spatial import cKDTree

from metairl_engine.coordinates import move_graph
from metairl_engine.grids import slipped_mdp
from metairl_engine.mdp import MDP
from metairl_engine.sim.benchmark import RewardWorld, wind_to_slip
from metairl_engine.sim.objectworld import nearest_by_colour


def graphworld_reward(mdp: MDP, objects: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """Objectworld's rule per state of ``mdp`` (S,) float32, given the objects' states and outer colours: +1
    within 3 hops of outer colour 0 and 2 of outer colour 1, −1 within 3 of colour 0 only."""
    hops = shortest_path(move_graph([mdp]), unweighted=True, indices=objects).T  # (S, objects)
    near0 = ((hops <= 3) & (outer[None, :] == 0)).any(axis=1)
    near1 = ((hops <= 2) & (outer[None, :] == 1)).any(axis=1)
    return np.where(near0 & near1, 1.0, np.where(near0, -1.0, 0.0)).astype(np.float32)


def make_graphworld(
    *,
    seed: int,
    n_states: int = 1024,
    n_neighbours: int = 4,
    n_colours: int = 2,
    gamma: float = 0.9,
    wind: float = 0.0,
) -> RewardWorld:
    """A random graph objectworld: ``n_states`` points, stay or move to one of the ``n_neighbours`` nearest;
    with ``wind``, objectworld's chance that a uniformly random action replaces the chosen one (the moves and
    so the reward stay the same: only which of them an action takes is random)."""
    rng = np.random.default_rng(seed)
    points = rng.random((n_states, 2))
    _, nearest = cKDTree(points).query(points, n_neighbours + 1)  # column 0: the point itself (stay)
    count = max(2, round(0.05 * n_states))
    objects = rng.choice(n_states, size=count, replace=False)
    inner, outer = rng.integers(n_colours, size=count), rng.integers(n_colours, size=count)
    distance = np.linalg.norm(points[:, None] - points[None, objects], axis=2) * np.sqrt(n_states)
    features = nearest_by_colour(distance, inner, outer, n_colours=n_colours, far=np.sqrt(2 * n_states))
    slip = wind_to_slip(wind, n_neighbours + 1)
    mdp = slipped_mdp(nearest.astype(np.int32), slip, gamma=gamma, features=features.astype(np.float32))
    return RewardWorld(size=round(np.sqrt(n_states)), reward=graphworld_reward(mdp, objects, outer), mdp=mdp)
