"""Garnet MDPs: b distinct next states per state and action whose probabilities sum to one, a reward linear in
binary features scaled to a largest |r| of 1, seeded."""

from __future__ import annotations

import numpy as np

from metairl_engine.planning import transition_matrix
from metairl_engine.sim.garnet import garnet_transitions, make_garnet


def test_each_state_and_action_leads_to_b_distinct_states_with_probabilities_summing_to_one() -> None:
    s, a, nxt, p = garnet_transitions(np.random.default_rng(0), n_states=6, n_actions=2, branching=3)
    assert len(s) == len(a) == len(nxt) == len(p) == 6 * 2 * 3
    for block in range(12):
        rows = slice(3 * block, 3 * block + 3)
        assert len(set(s[rows])) == 1 and len(set(a[rows])) == 1  # one (s, a) per block
        assert len(set(nxt[rows])) == 3 and (p[rows] > 0).all()
        assert np.isclose(p[rows].sum(), 1.0)
    assert (s[::6] == np.arange(6)).all() and (a[:6] == [0, 0, 0, 1, 1, 1]).all()


def test_a_world_s_reward_is_linear_in_its_binary_features_and_seeded() -> None:
    world = make_garnet(seed=3, n_states=25)
    mdp = world.mdp
    assert mdp.layout is None and mdp.features is not None and mdp.n_actions == 4 and world.size == 5
    assert set(np.unique(mdp.features)) <= {0.0, 1.0}
    weights, *_ = np.linalg.lstsq(mdp.features, world.reward, rcond=None)
    np.testing.assert_allclose(mdp.features @ weights, world.reward, atol=1e-5)
    assert np.isclose(np.abs(world.reward).max(), 1.0)
    np.testing.assert_allclose(transition_matrix(mdp).toarray().sum(axis=1), 1.0, rtol=1e-6)
    np.testing.assert_array_equal(world.reward, make_garnet(seed=3, n_states=25).reward)
    assert not np.array_equal(world.reward, make_garnet(seed=4, n_states=25).reward)
    assert make_garnet(seed=3, n_states=25, with_features=False).mdp.features is None
