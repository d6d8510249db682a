"""Levine's objectworld generator and its multi-task form: the published rule on hand-checked cells."""

from __future__ import annotations

import math

import numpy as np

from metairl_engine import validate_trajectories
from metairl_engine.metrics import expected_value_difference
from metairl_engine.planning import transition_matrix, value_iteration
from metairl_engine.sim.benchmark import goal_tasks, single_task
from metairl_engine.sim.objectworld import Objects, make_objectworld, objectworld_features, objectworld_reward
from metairl_engine.sim.terrain import demonstrator_policy

# Object A at (0, 0): inner colour 1, outer 0; object B at (4, 0): inner 0, outer 1.
TWO_OBJECTS = Objects(xy=np.array([[0, 0], [4, 0]]), inner=np.array([1, 0]), outer=np.array([0, 1]))


def test_reward_follows_the_published_rule_on_a_hand_checked_grid() -> None:
    # +1: Manhattan ≤ 3 of A and ≤ 2 of B; −1: ≤ 3 of A only; rows are y = 0 … 4.
    expected = np.array(
        [
            [-1, -1, 1, 1, 0],
            [-1, -1, -1, 0, 0],
            [-1, -1, 0, 0, 0],
            [-1, 0, 0, 0, 0],
            [0, 0, 0, 0, 0],
        ]
    )
    np.testing.assert_array_equal(objectworld_reward(5, TWO_OBJECTS).reshape(5, 5), expected)


def test_features_are_euclidean_distances_per_inner_then_outer_colour() -> None:
    continuous = objectworld_features(5, TWO_OBJECTS, n_colours=2, discrete=False)
    cell = 1 * 5 + 1  # (1, 1): √2 from A, √10 from B
    np.testing.assert_allclose(
        continuous[cell], [np.sqrt(10), np.sqrt(2), np.sqrt(2), np.sqrt(10)], rtol=1e-6
    )
    discrete = objectworld_features(5, TWO_OBJECTS, n_colours=2, discrete=True)
    assert discrete.shape == (25, 4 * 5)
    np.testing.assert_array_equal(discrete[cell, 5:10], [0, 1, 1, 1, 1])  # √2 < d for d = 2 … 5


def test_wind_replaces_the_action_by_a_uniform_one_of_five() -> None:
    world, _ = make_objectworld(seed=0, size=5, n_objects=3, wind=0.5)
    p = transition_matrix(world.mdp).toarray()
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    centre = 2 * 5 + 2
    east = p[centre * 5 + 0]  # action 0 (east) from the centre
    assert np.isclose(east[centre + 1], 1 - 0.5 + 0.5 / 5) and np.isclose(east[centre], 0.5 / 5)


def test_evd_is_zero_for_the_true_reward_and_positive_for_a_constant_one() -> None:
    world, _ = make_objectworld(seed=1, size=8, n_objects=6)
    assert np.ptp(world.reward) > 0
    assert abs(expected_value_difference(world.mdp, world.reward, world.reward)) < 1e-6
    assert expected_value_difference(world.mdp, world.reward, np.zeros_like(world.reward)) > 0.01


def test_goal_tasks_add_a_bonus_at_each_goal_and_demonstrate_valid_paths() -> None:
    world, _ = make_objectworld(seed=2, size=8, n_objects=6)
    tasks = goal_tasks(world, n_tasks=3, n_demos=4, seed=0, goal_bonus=10.0)
    for task in tasks:
        expected = world.reward.astype(np.float64)
        expected[task.goal] += 10.0
        np.testing.assert_allclose(task.true_reward, expected)
        validate_trajectories(world.mdp, task.trajectories)
        assert all(tr.states[0] != task.goal for tr in task.trajectories)
    single = single_task(world, n_demos=5, seed=0)
    assert [len(tr.actions) for tr in single.trajectories] == [8] * 5


def test_an_infinitely_rational_demonstrator_takes_only_optimal_actions() -> None:
    world, _ = make_objectworld(seed=3, size=8, n_objects=6)
    p = transition_matrix(world.mdp)
    q_star = value_iteration(p, world.reward, gamma=world.mdp.gamma, backup="max").q
    optimal = demonstrator_policy(p, world.reward, gamma=world.mdp.gamma, rationality=math.inf)
    best = q_star >= q_star.max(axis=1, keepdims=True) - 1e-12
    np.testing.assert_allclose(optimal.sum(axis=1), 1.0)
    assert (optimal[~best] == 0).all()
    # Every demonstrated action is one of the optimal ones; a Boltzmann demonstrator's are not.
    task = single_task(world, n_demos=20, seed=0, rationality=math.inf)
    assert all(best[s, a] for tr in task.trajectories for s, a in zip(tr.states, tr.actions, strict=False))
    noisy = single_task(world, n_demos=20, seed=0, rationality=0.5)
    assert not all(
        best[s, a] for tr in noisy.trajectories for s, a in zip(tr.states, tr.actions, strict=False)
    )
