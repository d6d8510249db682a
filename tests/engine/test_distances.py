"""EPIC and STARC with dynamics (`metairl_engine.distances`): shaping-invariant, scale- and shift-invariant,
and not blind: a permuted reward is far; bootstrap intervals bracket the estimate."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from metairl_engine import MDP
from metairl_engine.distances import (
    Distances,
    canonicalise,
    distances,
    pairwise_epic,
    shaped,
    shaping_operator,
    state_action_weights,
)
from metairl_engine.grids import grid_mdp
from metairl_engine.planning import transition_matrix


@pytest.fixture(scope="module", params=[0.0, 0.2], ids=["deterministic", "slippery"])
def world(request: pytest.FixtureRequest) -> tuple[MDP, np.ndarray]:
    """A 6×5 grid (4 moves and stay, γ 0.9), deterministic or with slip, and a state reward on it."""
    mdp = grid_mdp(width=6, height=5, moves=4, stay=True, slip=request.param, gamma=0.9)
    reward = np.random.default_rng(1).normal(size=mdp.n_states)
    return mdp, reward


def dist(mdp: MDP, a: np.ndarray, b: np.ndarray, **kwargs: Any) -> Distances:
    return distances(
        a,
        b,
        transitions=transition_matrix(mdp),
        gamma=mdp.gamma,
        n_actions=mdp.n_actions,
        **kwargs,
    )


def test_a_potential_shaped_copy_is_at_distance_zero(world: tuple[MDP, np.ndarray]) -> None:
    mdp, reward = world
    potential = np.random.default_rng(2).normal(scale=5.0, size=mdp.n_states)
    copy = shaped(
        reward, potential, transitions=transition_matrix(mdp), gamma=mdp.gamma, n_actions=mdp.n_actions
    )
    assert copy.shape == (mdp.n_states, mdp.n_actions) and np.abs(copy - reward[:, None]).max() > 1
    for weights in (None, np.random.default_rng(3).random(mdp.n_states)):
        d = dist(mdp, reward, copy, state_weights=weights)
        assert d.epic == pytest.approx(0.0, abs=1e-6) and d.starc == pytest.approx(0.0, abs=1e-6)
        # Shaping, a positive scale and a shift together change nothing either.
        d = dist(mdp, reward, 3.0 * copy + 7.0, state_weights=weights)
        assert d.epic == pytest.approx(0.0, abs=1e-6) and d.starc == pytest.approx(0.0, abs=1e-6)


def test_a_permuted_or_negated_reward_is_far(world: tuple[MDP, np.ndarray]) -> None:
    mdp, reward = world
    permuted = reward[np.random.default_rng(4).permutation(reward.size)]
    d = dist(mdp, reward, permuted)
    assert d.epic > 0.3 and d.starc > 0.3
    opposite = dist(mdp, reward, -reward)
    assert opposite.epic == pytest.approx(1.0, abs=1e-9) and opposite.starc == pytest.approx(1.0, abs=1e-9)


def test_canonicalisation_removes_exactly_the_shaping(world: tuple[MDP, np.ndarray]) -> None:
    mdp, reward = world
    T = transition_matrix(mdp)
    G = shaping_operator(T, mdp.gamma, mdp.n_actions)
    w = state_action_weights(None, mdp.n_states, mdp.n_actions)
    r = np.repeat(reward, mdp.n_actions)
    c = canonicalise(r, G, w)
    # C(R) is R minus a shaping term, and orthogonal (under D) to every shaping term: the least-norm representative.
    phi = np.linalg.lstsq(G.toarray(), r - c, rcond=None)[0]
    np.testing.assert_allclose(G @ phi, r - c, atol=1e-8)
    np.testing.assert_allclose(G.T @ (w * c), 0.0, atol=1e-10)
    # A constant reward is all shaping (Φ = −c / (1 − γ)); up to the float32 rounding of stored probabilities.
    np.testing.assert_allclose(canonicalise(np.full_like(r, 4.0), G, w), 0.0, atol=1e-5)


def test_rewards_canonicalised_together_are_each_the_least_norm_representative_even_with_unweighted_states(
    world: tuple[MDP, np.ndarray],
) -> None:
    mdp, _ = world
    G = shaping_operator(transition_matrix(mdp), mdp.gamma, mdp.n_actions)
    state_weights = np.random.default_rng(5).random(mdp.n_states) * (np.arange(mdp.n_states) % 3 > 0)
    w = state_action_weights(state_weights, mdp.n_states, mdp.n_actions)  # a third of the states weigh 0
    rewards = np.random.default_rng(6).normal(size=(3, mdp.n_states * mdp.n_actions))
    together = canonicalise(rewards, G, w)
    assert together.shape == rewards.shape
    for r, c in zip(rewards, together, strict=True):
        np.testing.assert_allclose(c, canonicalise(r, G, w), atol=1e-8)
        # Dense least squares under D: what the weighted entries of C(R) must be.
        root = np.sqrt(w)
        phi = np.linalg.lstsq(root[:, None] * G.toarray(), root * r, rcond=None)[0]
        weighted = w > 0
        np.testing.assert_allclose(c[weighted], (r - G @ phi)[weighted], atol=1e-7)


def test_bootstrap_interval_brackets_the_estimate_and_is_reproducible(
    world: tuple[MDP, np.ndarray],
) -> None:
    mdp, reward = world
    noisy = reward + np.random.default_rng(5).normal(scale=0.8, size=reward.size)
    d = dist(mdp, reward, noisy, bootstrap=200)
    assert d.n_bootstrap == 200 and d.epic_interval is not None and d.starc_interval is not None
    assert d.epic_interval.low <= d.epic <= d.epic_interval.high
    assert d.starc_interval.low <= d.starc <= d.starc_interval.high
    assert d.epic_interval.high - d.epic_interval.low > 0
    assert dist(mdp, reward, noisy, bootstrap=200) == d


def test_occupancy_weights_only_count_weighted_states(world: tuple[MDP, np.ndarray]) -> None:
    mdp, reward = world
    weights = np.zeros(mdp.n_states)
    weights[:10] = 1.0
    other = reward.copy()
    other[10:] = np.random.default_rng(6).normal(size=reward.size - 10)  # differs only where weight is 0 …
    uniform = dist(mdp, reward, other)
    occupancy = dist(mdp, reward, other, state_weights=weights)
    assert uniform.epic > 0.2
    assert occupancy.epic < uniform.epic  # … and matters less once those states are not weighted
    with pytest.raises(ValueError, match="not all zero"):
        dist(mdp, reward, other, state_weights=np.zeros(mdp.n_states))


@pytest.mark.parametrize("weighted", [False, True], ids=["uniform", "a third unweighted"])
def test_the_pairwise_matrix_is_each_pairs_epic_for_state_and_state_action_rewards(
    world: tuple[MDP, np.ndarray], weighted: bool
) -> None:
    mdp, reward = world
    T = transition_matrix(mdp)
    rng = np.random.default_rng(7)
    weights = rng.random(mdp.n_states) * (np.arange(mdp.n_states) % 3 > 0) if weighted else None
    shaped_copy = shaped(
        reward, rng.normal(size=mdp.n_states), transitions=T, gamma=mdp.gamma, n_actions=mdp.n_actions
    )
    for rewards in (
        [reward, 3.0 * reward + 1.0, rng.normal(size=mdp.n_states), -reward],
        [reward, shaped_copy, rng.normal(size=(mdp.n_states, mdp.n_actions))],
    ):
        matrix = pairwise_epic(
            rewards, transitions=T, gamma=mdp.gamma, n_actions=mdp.n_actions, state_weights=weights
        )
        expected = [[dist(mdp, a, b, state_weights=weights).epic for b in rewards] for a in rewards]
        np.testing.assert_allclose(matrix, expected, atol=1e-6)
        assert matrix[0, 1] == pytest.approx(0.0, abs=1e-6)  # a positive scale, a shift or shaping: the same
    # A constant is all shaping (up to the float32 transitions): it correlates with nothing.
    constant = pairwise_epic(
        [reward, np.full(mdp.n_states, 2.0)], transitions=T, gamma=mdp.gamma, n_actions=mdp.n_actions
    )
    assert constant[0, 1] == pytest.approx(np.sqrt(0.5))
