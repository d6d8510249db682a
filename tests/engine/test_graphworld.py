"""Objectworld's rule on a random geometric graph: hops as the radii, on a hand-checked path; a world with
features and no layout that the engine fits."""

from __future__ import annotations

import numpy as np

from metairl_engine.sim.graphworld import graphworld_reward, hops_between, make_graphworld

# Eight states on a line: stay, step left, step right (the ends stay put).
LINE = np.stack([np.arange(8), np.maximum(np.arange(8) - 1, 0), np.minimum(np.arange(8) + 1, 7)], axis=1)


def test_hops_count_moves_either_way_round() -> None:
    hops = hops_between(LINE)
    np.testing.assert_array_equal(hops[0], np.arange(8))
    # Moving right only would not reach state 2 from state 5; either way round it is 3 hops.
    one_way = np.stack([np.arange(8), np.minimum(np.arange(8) + 1, 7)], axis=1)
    assert hops_between(one_way)[5, 2] == 3


def test_reward_follows_objectworlds_rule_with_hops_for_radii() -> None:
    # Outer colour 0 at state 0, outer colour 1 at state 5: within 3 of the first is states 0 … 3, within 2
    # of the second states 3 … 7, so state 3 is +1, states 0 … 2 are −1 and the rest 0.
    reward = graphworld_reward(hops_between(LINE), np.array([0, 5]), np.array([0, 1]))
    np.testing.assert_array_equal(reward, [-1, -1, -1, 1, 0, 0, 0, 0])


def test_a_world_has_distance_features_no_layout_and_is_seeded() -> None:
    world = make_graphworld(seed=3, n_states=256)
    mdp = world.mdp
    assert mdp.layout is None and mdp.n_actions == 5 and mdp.features is not None
    assert mdp.features.shape == (256, 4) and float(mdp.features.min()) == 0.0  # objects are at distance 0
    assert set(np.unique(world.reward)) <= {-1.0, 0.0, 1.0}
    np.testing.assert_array_equal(world.reward, make_graphworld(seed=3, n_states=256).reward)
    assert not np.array_equal(world.reward, make_graphworld(seed=4, n_states=256).reward)
