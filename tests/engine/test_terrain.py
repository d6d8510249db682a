"""The hilly-terrain experiment generator: seeded, valid demonstrations that head for the goal."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from metairl_engine import validate_trajectories
from metairl_engine.grids import grid_mdp
from metairl_engine.sim.terrain import make_tasks, make_world


def test_same_seed_same_world_and_tasks() -> None:
    a, b = make_world(size=8, seed=3), make_world(size=8, seed=3)
    assert np.array_equal(a.cost, b.cost) and not np.array_equal(a.cost, make_world(size=8, seed=4).cost)
    ta, tb = make_tasks(a, n_tasks=2, n_demos=2, seed=1), make_tasks(b, n_tasks=2, n_demos=2, seed=1)
    assert [t.goal for t in ta] == [t.goal for t in tb]
    assert all(
        np.array_equal(x.states, y.states)
        for s, t in zip(ta, tb, strict=True)
        for x, y in zip(s.trajectories, t.trajectories, strict=True)
    )


def test_true_reward_is_negative_cost_plus_goal_bonus() -> None:
    world = make_world(size=8, n_hills=4, seed=0)
    (task,) = make_tasks(world, n_tasks=1, n_demos=1, seed=0, goal_bonus=3.0)
    expected = -world.cost.astype(np.float64)
    expected[task.goal] += 3.0
    np.testing.assert_allclose(task.true_reward, expected, rtol=1e-6)
    assert world.cost.min() > 0 and world.mdp.n_states == 64


def test_demonstrations_are_valid_and_mostly_reach_the_goal() -> None:
    world = make_world(size=8, seed=1)
    tasks = make_tasks(world, n_tasks=3, n_demos=10, seed=2)
    reached = []
    for task in tasks:
        validate_trajectories(world.mdp, task.trajectories)
        assert all(tr.states[0] != task.goal for tr in task.trajectories)
        assert all(len(tr.actions) <= 3 * world.size for tr in task.trajectories)
        reached += [tr.states[-1] == task.goal for tr in task.trajectories]
    assert np.mean(reached) >= 0.8


def test_demonstrations_on_a_slippery_world_follow_its_slips() -> None:
    world = make_world(size=8, seed=1)
    slippery = replace(world, mdp=grid_mdp(width=8, height=8, moves=8, stay=True, gamma=0.9, slip=0.5))
    tasks = make_tasks(slippery, n_tasks=2, n_demos=10, seed=2)
    planned = world.mdp.next_state
    assert planned is not None
    slipped = 0
    for task in tasks:
        validate_trajectories(slippery.mdp, task.trajectories)  # every step has a positive probability
        for tr in task.trajectories:
            slipped += int(np.sum(planned[tr.states[:-1], tr.actions] != tr.states[1:]))
    assert slipped > 0  # with slip 0.5 some steps land where the chosen move does not lead
