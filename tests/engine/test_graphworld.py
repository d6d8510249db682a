"""Objectworld's rule on a random geometric graph: hops as the radii, on a hand-checked path; a seeded world
with distance features and no layout."""

from __future__ import annotations

import numpy as np

from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix
from metairl_engine.sim.graphworld import graphworld_reward, make_graphworld

# Eight states on a line, moving right only (the last stays put): hops count moves either way round.
LINE = MDP.build(gamma=0.9, next_state=np.stack([np.arange(8), np.minimum(np.arange(8) + 1, 7)], axis=1))


def test_reward_follows_objectworlds_rule_with_hops_either_way_round_for_radii() -> None:
    # Outer colour 0 at state 0, outer colour 1 at state 5: within 3 of the first is states 0 … 3, within 2
    # of the second states 3 … 7 (state 3 only by moving left, which no action does), so state 3 is +1,
    # states 0 … 2 are −1 and the rest 0.
    reward = graphworld_reward(LINE, np.array([0, 5]), np.array([0, 1]))
    np.testing.assert_array_equal(reward, [-1, -1, -1, 1, 0, 0, 0, 0])


def test_a_world_has_distance_features_no_layout_and_is_seeded() -> None:
    world = make_graphworld(seed=3, n_states=256)
    mdp = world.mdp
    assert mdp.layout is None and mdp.n_actions == 5 and mdp.features is not None
    assert mdp.features.shape == (256, 4) and float(mdp.features.min()) == 0.0  # objects are at distance 0
    assert set(np.unique(world.reward)) <= {-1.0, 0.0, 1.0}
    np.testing.assert_array_equal(world.reward, make_graphworld(seed=3, n_states=256).reward)
    assert not np.array_equal(world.reward, make_graphworld(seed=4, n_states=256).reward)


def test_wind_randomises_which_move_an_action_takes_and_keeps_the_moves_and_the_reward() -> None:
    still, windy = make_graphworld(seed=3, n_states=64), make_graphworld(seed=3, n_states=64, wind=0.3)
    assert still.mdp.next_state is not None and windy.mdp.next_state is None
    np.testing.assert_array_equal(windy.reward, still.reward)
    np.testing.assert_array_equal(windy.mdp.features, still.mdp.features)
    p = transition_matrix(windy.mdp).toarray().reshape(64, 5, 64)
    np.testing.assert_allclose(p.sum(axis=2), 1.0)
    # The chosen move with 1 − 0.3 + 0.3/5, each other one of the state's five (itself, its 4 nearest) 0.3/5.
    for state in (0, 17):
        targets = still.mdp.next_state[state]
        assert len(set(targets)) == 5
        np.testing.assert_allclose(p[state][:, targets], np.full((5, 5), 0.06) + 0.7 * np.eye(5), rtol=1e-6)
