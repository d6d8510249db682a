"""The IRL toolkit's gridworld generator: macro-cell rewards, the split-table features, slipping moves."""

from __future__ import annotations

import numpy as np
import pytest

from metairl_engine.metrics import expected_value_difference
from metairl_engine.planning import transition_matrix
from metairl_engine.sim.gridworld import macro_cell_reward, make_gridworld, split_table


def test_split_table_codes_x_then_y_as_thresholds() -> None:
    features = split_table(4)
    assert features.shape == (16, 6)
    np.testing.assert_array_equal(features[0], [0, 0, 0, 0, 0, 0])  # (x 0, y 0)
    np.testing.assert_array_equal(features[2], [1, 1, 0, 0, 0, 0])  # (x 2, y 0): x ≥ 1, x ≥ 2
    np.testing.assert_array_equal(features[4 * 3 + 1], [1, 0, 0, 1, 1, 1])  # (x 1, y 3)


def test_each_macro_cell_holds_its_reward_on_its_block() -> None:
    reward = macro_cell_reward(np.array([[1.0, 2.0], [3.0, 4.0]]), 2).reshape(4, 4)  # [y, x]
    np.testing.assert_array_equal(reward, [[1, 1, 2, 2], [1, 1, 2, 2], [3, 3, 4, 4], [3, 3, 4, 4]])


def test_rewards_are_sparse_powers_of_uniforms_on_the_published_scale() -> None:
    world = make_gridworld(seed=0)
    assert world.reward.shape == (1024,) and world.mdp.features is not None
    assert world.mdp.features.shape == (1024, 62)
    assert world.reward.min() >= 0.0 and world.reward.max() <= 100.0
    assert np.median(world.reward) < 10.0  # U⁸: most macro cells near 0
    assert len(np.unique(world.reward)) == 64  # one value per 4×4 macro cell


def test_the_chosen_move_is_taken_with_the_determinism_and_evd_separates_true_from_constant() -> None:
    world = make_gridworld(seed=1, size=8, block=2)
    p = transition_matrix(world.mdp)  # (S·A, S), row s·A + a
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    middle = 8 * 3 + 3
    rows = p[middle * 5 : middle * 5 + 5].toarray()  # a cell off the edges: five distinct targets
    np.testing.assert_allclose(np.sort(rows, axis=1)[:, -2:], [[0.075, 0.7]] * 5)  # own target, others 0.3/4
    assert abs(expected_value_difference(world.mdp, world.reward, world.reward)) < 1e-6
    assert expected_value_difference(world.mdp, world.reward, np.zeros_like(world.reward)) > 0.01


def test_a_size_that_is_not_whole_macro_cells_is_refused() -> None:
    with pytest.raises(ValueError, match="macro cells"):
        make_gridworld(seed=0, size=10, block=4)
