"""Wulfmeier et al.'s binaryworld generator: neighbourhood features and the 4-blue / 5-blue reward rule."""

from __future__ import annotations

import numpy as np

from metairl_engine.metrics import expected_value_difference
from metairl_engine.planning import transition_matrix
from metairl_engine.sim.binaryworld import binaryworld_features, binaryworld_reward, make_binaryworld


def test_reward_counts_blue_cells_of_the_3x3_neighbourhood_off_grid_red() -> None:
    blue = np.zeros((5, 5), dtype=bool)
    blue[0:2, 0:2] = True  # a 2×2 blue block in the corner ...
    blue[2, 0] = True  # ... and one more below it (row y = 2, x = 0)
    features = binaryworld_features(blue)
    reward = binaryworld_reward(features).reshape(5, 5)
    assert features.shape == (25, 9)
    np.testing.assert_array_equal(features[0], [0, 0, 0, 0, 1, 1, 0, 1, 1])  # corner (0, 0): 4 blue
    assert reward[0, 0] == 1  # 4 blue (the corner block; off-grid cells are red)
    assert reward[1, 1] == -1  # 5 blue: the block and (x 0, y 2)
    assert reward[1, 0] == -1  # 5 blue
    assert reward[3, 3] == 0  # none blue
    assert reward[3, 1] == 0  # 1 blue: (x 0, y 2)


def test_windy_transitions_are_distributions_and_evd_separates_true_from_constant() -> None:
    world = make_binaryworld(seed=0, size=6)
    np.testing.assert_allclose(transition_matrix(world.mdp).sum(axis=1), 1.0)
    assert abs(expected_value_difference(world.mdp, world.reward, world.reward)) < 1e-6
    assert expected_value_difference(world.mdp, world.reward, np.zeros_like(world.reward)) > 0.01
