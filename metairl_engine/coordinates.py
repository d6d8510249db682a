"""Coordinates of the states of an MDP uploaded without features, for the networks to generalise with.

With one-hot inputs (the paper's tabular network) a state no demonstration reaches gets its reward from the
sharing loss alone, nothing carrying over from its neighbours: on the terrain benchmarks task rewards then
correlate 0.26 (repo generator) and 0.05 (frozen) with the truth, against 0.56 and 0.60 with (x, y)
features (`benchmarks/RESULTS.md`, "MDPs without features"). So a featureless MDP gets coordinates:

- with a ``layout`` (states tile ``channels`` panels of ``height`` × ``width``, ``state = (channel · height +
  y) · width + x``): x and y normalised to [0, 1], plus a one-hot of the channel when there are several —
  `grids.layout_features`, exactly the features `grids.grid_mdp` gives a plain or velocity grid;
- without one: positions recovered from the transition graph by landmark multidimensional scaling (de Silva
  & Tenenbaum 2003) of the hop distances between states (how many steps apart, either way round, under any
  task's transitions), in two dimensions, each normalised to [0, 1]. On a grid this recovers its two axes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import shortest_path

from metairl_engine.grids import GRAPH_DIMENSIONS, layout_features
from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix

COORDINATE_OCTAVES = 2
"""Octaves of the sinusoids of the coordinates the task networks see (`FitConfig.task_coordinates`,
`networks.fourier_features`): a goal is
a bump at one place, which a ReLU MLP builds slowly from raw coordinates (spectral bias) and directly from
waves down to a quarter of the grid. Chosen on the multi-task objectworld worlds of `benchmarks/FAMILIES.md`
(world 0, 10 demonstrations, Pearson / EVD÷random: raw 0.44 / 0.32, 2 octaves 0.61 / 0.12, 3 octaves
0.67 / 0.10; with 3 demonstrations that wander (goal bonus 3), worlds 0 and 2, Pearson 0.48 and 0.31 with 3
octaves against 0.54 and 0.48 with 2)."""

TASK_COORDINATE_COLUMNS = GRAPH_DIMENSIONS * (1 + 2 * COORDINATE_OCTAVES)
"""Columns `FitConfig.task_coordinates` adds to the task networks' inputs of an MDP with features: x, y and
their sine and cosine at each of COORDINATE_OCTAVES octaves (10). A layout of several panels would add its
channel one-hot too, but the grids that have one (velocity grids) have these coordinates as their features,
which the fit then leaves as they are."""

LANDMARKS = 64
"""States whose hop distances to every state the graph embedding measures (all of them on smaller MDPs)."""


def state_coordinates(mdps: Sequence[MDP], *, seed: int) -> np.ndarray | None:
    """(S, F) float32 coordinates of the states the ``mdps`` share, from a layout or their transition graph.

    None when the graph gives no spread at all (a single state, or no transitions between distinct states).
    """
    layout = next((m.layout for m in mdps if m.layout is not None), None)
    if layout is not None:
        return layout_features(layout)
    return graph_coordinates(mdps, seed=seed)


def move_graph(mdps: Sequence[MDP]) -> sp.csr_matrix:
    """The undirected union of the ``mdps``' transition graphs (S, S): s and s' are joined where any action of
    any of them moves one to the other with positive probability (weights count such moves; hop counts ignore
    them)."""
    n_states = mdps[0].n_states
    adjacency = sp.csr_matrix((n_states, n_states))
    for mdp in {id(m): m for m in mdps}.values():
        p = transition_matrix(mdp).tocoo()
        adjacency = adjacency + sp.csr_matrix(
            (np.ones(p.nnz), (p.row // mdp.n_actions, p.col)), shape=(n_states, n_states)
        )
    return (adjacency + adjacency.T).tocsr()


def features_are_positions(mdps: Sequence[MDP], features: np.ndarray) -> bool:
    """Whether ``features`` (S, F) say only where each state is: no two states share them, and the moves
    between states shift them along at most ``n_actions`` directions (a shift and its reverse one direction),
    so they are cells of a lattice the moves step along, such as each cell's (x, y). Such features tell the
    networks nothing the transitions do not. Shifts are compared to 1e-6 of the features' largest range."""
    n_states = mdps[0].n_states
    if len(np.unique(features, axis=0)) < n_states:
        return False
    moves = sp.triu(move_graph(mdps), k=1).tocoo()
    if moves.nnz == 0:
        return False
    span = float(np.ptp(features, axis=0).max()) or 1.0
    shifts = np.round((features[moves.col] - features[moves.row]) / (span * 1e-6)).astype(np.int64)
    leading = shifts[np.arange(len(shifts)), (shifts != 0).argmax(axis=1)]
    directions = shifts * np.sign(leading)[:, None]  # a move and its reverse are one direction
    return len(np.unique(directions, axis=0)) <= mdps[0].n_actions


def graph_coordinates(mdps: Sequence[MDP], *, seed: int) -> np.ndarray | None:
    """Landmark MDS of the hop distances of the undirected union of the ``mdps``' transition graphs.

    B = −½ J D²_L J over the m landmarks (J centres), its top eigenpairs (λ_k, v_k), and every state's
    position x_k(s) = −½ Σ_l v_k(l)/√λ_k · (D²(l, s) − mean_l' D²(l, l')) (de Silva & Tenenbaum, eq. 5).
    States unreachable from a landmark are put one hop beyond the farthest reachable state.
    """
    n_states = mdps[0].n_states
    adjacency = move_graph(mdps)
    rng = np.random.default_rng(seed)
    landmarks = np.sort(rng.choice(n_states, size=min(LANDMARKS, n_states), replace=False))
    hops = shortest_path(adjacency, unweighted=True, indices=landmarks)  # (m, S)
    reachable = np.isfinite(hops)
    hops[~reachable] = (hops[reachable].max() if reachable.any() else 0.0) + 1.0
    squared = hops**2
    between = squared[:, landmarks]  # (m, m)
    m = len(landmarks)
    centring = np.eye(m) - 1.0 / m
    values, vectors = np.linalg.eigh(-0.5 * centring @ between @ centring)
    order = np.argsort(values)[::-1][:GRAPH_DIMENSIONS]
    keep = order[values[order] > 1e-9 * max(values.max(), 1e-300)]
    if keep.size == 0:
        return None
    positions = (
        -0.5 * (squared - between.mean(axis=1, keepdims=True)).T @ (vectors[:, keep] / np.sqrt(values[keep]))
    )
    low, high = positions.min(axis=0), positions.max(axis=0)
    return ((positions - low) / np.where(high > low, high - low, 1.0)).astype(np.float32)
