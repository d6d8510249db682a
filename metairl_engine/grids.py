"""Grid-world MDPs built server side (docs/api.md, "Grid": ``kind: grid``): plain grids and the paper's velocity grid.

numpy only. One compass table, `DIRECTIONS`, is used by the grids, the motion pipeline and the docs:
index 0..7 = E, NE, N, NW, W, SW, S, SE as (dx, dy) with +y pointing *forward* on the force plate.
Plain grid: ``state = y * width + x``. Velocity grid: ``state = (direction * height + y) * width + x``,
so a reward reshapes to ``(8, height, width)`` (mdp.py's layout convention).
"""

from __future__ import annotations

import numpy as np

from metairl_engine.errors import Issue, check
from metairl_engine.mdp import MDP, Layout

DIRECTIONS = np.array([(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)], dtype=np.int64)
"""The 8 compass moves (dx, dy), counter-clockwise from east; +y is forward on the plate. Shape (8, 2)."""

DIRECTION_NAMES = (
    "right",
    "forward right",
    "forward",
    "forward left",
    "left",
    "backward left",
    "backward",
    "backward right",
)
"""Clinical instruction for each entry of `DIRECTIONS` (same index)."""

STAY = np.array([[0, 0]], dtype=np.int64)
"""The displacement of the optional "stay" action (always the last action of a plain grid)."""

MAX_GRID_STATES = 4_000_000
"""Largest grid built on request (a 4M-state table is ~130 MB); bigger MDPs must be uploaded."""

_LOOKUP = np.full((3, 3), -1, dtype=np.int64)
_LOOKUP[DIRECTIONS[:, 1] + 1, DIRECTIONS[:, 0] + 1] = np.arange(8)


def direction_index(dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
    """Index into `DIRECTIONS` of unit king moves (dx, dy ∈ {-1, 0, 1}); -1 where the move is (0, 0)."""
    return _LOOKUP[np.asarray(dy) + 1, np.asarray(dx) + 1]


def grid_moves(*, moves: int, stay: bool) -> np.ndarray:
    """Displacements (A, 2) of a plain grid's actions: E, N, W, S (moves=4) or all 8, then stay if asked."""
    table = DIRECTIONS[::2] if moves == 4 else DIRECTIONS
    return np.concatenate([table, STAY]) if stay else table


def velocity_state(
    x: np.ndarray | int, y: np.ndarray | int, direction: np.ndarray | int, *, width: int, height: int
) -> np.ndarray:
    """Velocity-grid state of cell (x, y) entered moving in `direction` (vectorised; int64)."""
    return (np.asarray(direction, dtype=np.int64) * height + y) * width + np.asarray(x, dtype=np.int64)


def velocity_coords(state: np.ndarray | int, *, width: int, height: int) -> tuple[np.ndarray, ...]:
    """Inverse of `velocity_state`: (x, y, direction) int64 arrays of the same shape as `state`."""
    rest, x = np.divmod(np.asarray(state, dtype=np.int64), width)
    direction, y = np.divmod(rest, height)
    return x, y, direction


def grid_mdp(
    *,
    width: int,
    height: int,
    moves: int | None = None,
    stay: bool = False,
    slip: float = 0.0,
    velocity: bool = False,
    gamma: float,
) -> MDP:
    """A validated grid MDP with layout and normalised-coordinate features (see the module docstring).

    ``moves`` defaults to 4 on a plain grid; a velocity grid has the 8 directions as actions (moves must be 8
    or omitted) and no stay action. ``slip``: probability that the chosen action is replaced by a uniformly
    random other one (sparse transitions, duplicate targets merged); 0 gives a deterministic table.
    Moving off the grid keeps the agent in its cell (on a velocity grid its velocity becomes the action).
    """
    moves = (8 if velocity else 4) if moves is None else moves
    _check_arguments(width=width, height=height, moves=moves, stay=stay, slip=slip, velocity=velocity)
    width, height = int(width), int(height)
    disp = DIRECTIONS if velocity else grid_moves(moves=moves, stay=stay)
    next_state = _cell_targets(width, height, disp)  # (W*H, A) target cell y*W + x
    if velocity:  # the target's channel is the action; the table is the same in every channel
        next_state = np.tile(np.arange(len(disp)) * (width * height) + next_state, (8, 1))
    layout = Layout(width=width, height=height, channels=8 if velocity else 1)
    features = layout_features(layout)
    return slipped_mdp(next_state, float(slip), gamma=gamma, features=features, layout=layout)


def slipped_mdp(
    next_state: np.ndarray,
    slip: float,
    *,
    gamma: float,
    features: np.ndarray | None,
    layout: Layout | None = None,
) -> MDP:
    """The MDP of the deterministic table ``next_state`` (S, A) whose chosen action is replaced, with probability
    ``slip``, by a uniformly random other one: the table itself at slip 0, else sparse transitions (`_slipped`)."""
    if slip == 0.0:
        return MDP.build(gamma=gamma, next_state=next_state, features=features, layout=layout)
    s, a, nxt, p = _slipped(next_state, slip)
    return MDP.build(
        gamma=gamma,
        n_states=next_state.shape[0],
        n_actions=next_state.shape[1],
        s=s,
        a=a,
        next=nxt,
        p=p,
        features=features,
        layout=layout,
    )


def _is_int(value: object) -> bool:
    """A real integer (Python or numpy), not a bool."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _check_arguments(*, width: int, height: int, moves: int, stay: bool, slip: float, velocity: bool) -> None:
    """Raise `InvalidInput` with request pointers for every unusable grid argument."""
    issues: list[Issue] = []
    for name, value in (("width", width), ("height", height)):
        if not _is_int(value) or value < 1:
            issues.append(Issue(f"/{name}", f"must be a positive integer, got {value!r}"))
    if moves not in (4, 8) or not _is_int(moves):
        issues.append(Issue("/moves", f"must be 4 or 8, got {moves!r}"))
    elif velocity and moves != 8:
        issues.append(
            Issue("/moves", "a velocity grid's actions are the 8 compass directions: use 8 or omit it")
        )
    if not (isinstance(slip, int | float | np.floating) and 0.0 <= float(slip) <= 1.0):
        issues.append(Issue("/slip", f"must be a probability in [0, 1], got {slip!r}"))
    if velocity and stay:
        issues.append(Issue("/stay", "a velocity grid has no stay action (every action sets a direction)"))
    check(issues)
    n_states = width * height * (8 if velocity else 1)
    if n_states > MAX_GRID_STATES:
        check([Issue("/width", f"the grid would have {n_states:,} states; at most {MAX_GRID_STATES:,}")])


def _cell_targets(width: int, height: int, disp: np.ndarray) -> np.ndarray:
    """Target cell ``y * width + x`` of every (cell, move), shape (W*H, A); off-grid moves stay put."""
    y, x = np.divmod(np.arange(width * height), width)
    nx = x[:, None] + disp[None, :, 0]
    ny = y[:, None] + disp[None, :, 1]
    inside = (nx >= 0) & (nx < width) & (ny >= 0) & (ny < height)
    return np.where(inside, ny * width + nx, (y * width + x)[:, None]).astype(np.int32)


GRAPH_DIMENSIONS = 2
"""Coordinates recovered from the transition graph of an MDP without features or layout (the leading ones of
the landmark MDS, `coordinates.graph_coordinates`)."""


def input_columns(n_features: int | None, layout: Layout | None, tabular_inputs: str) -> int | None:
    """How many columns the networks' state inputs have: the MDP's features, else (``tabular_inputs=
    "coordinates"``) its layout's coordinates (`layout_features`) or the graph's; None for one-hot inputs."""
    if n_features is not None:
        return n_features
    if tabular_inputs != "coordinates":
        return None
    if layout is None:
        return GRAPH_DIMENSIONS
    return 2 + (layout.channels if layout.channels > 1 else 0)


def layout_features(layout: Layout) -> np.ndarray:
    """(S, 2) normalised (x / (width − 1), y / (height − 1)) in [0, 1] per state, then an (S, channels)
    one-hot of its panel when there are several (a velocity grid's direction); float32."""
    per_panel = layout.width * layout.height
    y, x = np.divmod(np.arange(per_panel), layout.width)
    xy = np.stack([x / max(layout.width - 1, 1), y / max(layout.height - 1, 1)], axis=1).astype(np.float32)
    xy = np.tile(xy, (layout.channels, 1))
    if layout.channels == 1:
        return xy
    channel = np.repeat(np.eye(layout.channels, dtype=np.float32), per_panel, axis=0)
    return np.concatenate([xy, channel], axis=1)


def _slipped(next_state: np.ndarray, slip: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sparse (s, a, next, p): action a is replaced by each other action with prob slip/(A-1).

    Targets repeated within a state's row (walls, stay) are merged, without a global sort: for every
    (s, a) and every distinct target g of row s, p = slip/(A-1) · #{b: T[s,b]=g} + (1-slip-slip/(A-1))·[T[s,a]=g].
    """
    n_actions = next_state.shape[1]
    other = slip / (n_actions - 1)
    targets = np.sort(next_state, axis=1)  # (S, A); each distinct target starts a run
    distinct = np.ones_like(targets, dtype=bool)
    distinct[:, 1:] = targets[:, 1:] != targets[:, :-1]
    hits = next_state[:, :, None] == targets[:, None, :]  # (S, a, k): does action a land on targets[s, k]
    p = other * hits.sum(axis=1, dtype=np.float64)[:, None, :] + (1.0 - slip - other) * hits
    keep = distinct[:, None, :] & (p > 0)
    s, a, k = np.nonzero(keep)
    return s, a, targets[s, k], p[keep]
