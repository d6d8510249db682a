"""Four rooms (Sutton, Precup & Singh 1999, Figure 2): 104 cells in four rooms joined by four one-cell
doorways, inside a 13 × 13 square of walls; five actions (four moves and stay, objectworld's set), a move into
a wall stays put, and with ``wind`` a uniformly random action replaces the chosen one.

The published world rewards only its goal; a demonstrator's shared reward here is a cost of 0.1 per step
everywhere with ``n_hazards`` cells of −1 and ``n_treasures`` of +1 at random open cells. The states are the
open cells only, so the MDP has no layout; its features, when kept, are each cell's (x, y). What it tests: a
reward made of a few cells, behind walls that make neighbours in the plane far apart in moves.
"""

from __future__ import annotations

import numpy as np

from metairl_engine.grids import slipped_mdp
from metairl_engine.sim.benchmark import RewardWorld, wind_to_slip

FOUR_ROOMS = (
    "wwwwwwwwwwwww",
    "w     w     w",
    "w     w     w",
    "w           w",
    "w     w     w",
    "w     w     w",
    "ww wwww     w",
    "w     www www",
    "w     w     w",
    "w     w     w",
    "w           w",
    "w     w     w",
    "wwwwwwwwwwwww",
)
"""The published map, top row first: ``w`` a wall, a blank an open cell."""

MOVES = ((1, 0), (0, -1), (-1, 0), (0, 1), (0, 0))
"""Each action's (dx, dy): right, up, left, down, stay."""


def open_cells() -> list[tuple[int, int]]:
    """The open cells' (x, y), row by row from the top: state k is cell k."""
    return [(x, y) for y, row in enumerate(FOUR_ROOMS) for x, c in enumerate(row) if c == " "]


def make_four_rooms(
    *,
    seed: int,
    wind: float = 0.1,
    gamma: float = 0.9,
    step_reward: float = -0.1,
    n_hazards: int = 6,
    n_treasures: int = 3,
    with_features: bool = True,
) -> RewardWorld:
    """A seeded four-rooms world: the hazards and treasures drawn among the open cells; ``size`` 11, the
    rooms' span, the horizon scale of the other families."""
    rng = np.random.default_rng(seed)
    cells = open_cells()
    index = {cell: k for k, cell in enumerate(cells)}
    next_state = np.array(
        [[index.get((x + dx, y + dy), index[(x, y)]) for dx, dy in MOVES] for x, y in cells], dtype=np.int32
    )
    reward = np.full(len(cells), step_reward, dtype=np.float32)
    special = rng.choice(len(cells), size=n_hazards + n_treasures, replace=False)
    reward[special[:n_hazards]], reward[special[n_hazards:]] = -1.0, 1.0
    features = np.array(cells, dtype=np.float32) if with_features else None
    mdp = slipped_mdp(next_state, wind_to_slip(wind, len(MOVES)), gamma=gamma, features=features)
    return RewardWorld(size=len(FOUR_ROOMS) - 2, reward=reward, mdp=mdp)
