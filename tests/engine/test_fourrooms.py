"""Four rooms: the published map's 104 open cells, walls that stop a move, doorways that let it through, and
a reward of a step cost with a few hazards and treasures."""

from __future__ import annotations

import numpy as np

from metairl_engine.planning import transition_matrix
from metairl_engine.sim.fourrooms import make_four_rooms, open_cells


def test_the_map_has_104_open_cells_in_four_rooms_joined_by_four_doorways() -> None:
    cells = open_cells()
    assert len(cells) == 104 and cells[0] == (1, 1)
    # The doorways: one cell with walls on two opposite sides, in the wall between two rooms.
    doorways = {(6, 3), (2, 6), (6, 10), (9, 7)}
    assert doorways <= set(cells)


def test_walls_stop_a_move_and_a_doorway_lets_it_through() -> None:
    world = make_four_rooms(seed=0, wind=0.0)
    index = {cell: k for k, cell in enumerate(open_cells())}
    next_state = world.mdp.next_state
    assert next_state is not None
    # From (5, 1), right is a wall: it stays; from (5, 3), right is the doorway (6, 3), then on to (7, 3).
    assert next_state[index[(5, 1)], 0] == index[(5, 1)]
    assert next_state[index[(5, 3)], 0] == index[(6, 3)]
    assert next_state[index[(6, 3)], 0] == index[(7, 3)]
    assert next_state[index[(1, 1)], 1] == index[(1, 1)]  # up from the top-left corner: the border wall
    assert (next_state[:, 4] == np.arange(104)).all()  # stay


def test_the_reward_is_a_step_cost_with_hazards_and_treasures_and_is_seeded() -> None:
    world = make_four_rooms(seed=5)
    hazards, treasures = int((world.reward == -1).sum()), int((world.reward == 1).sum())
    assert (hazards, treasures, int(np.isclose(world.reward, -0.1).sum())) == (6, 3, 95)
    assert (
        world.mdp.layout is None and world.mdp.features is not None and world.mdp.features.shape == (104, 2)
    )
    np.testing.assert_allclose(transition_matrix(world.mdp).toarray().sum(axis=1), 1.0, rtol=1e-6)
    assert not np.array_equal(world.reward, make_four_rooms(seed=6).reward)
    assert make_four_rooms(seed=5, with_features=False).mdp.features is None
