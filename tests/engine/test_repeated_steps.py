"""A deterministic demonstrator's repeated steps count once: it is recognised from the demonstrations
alone, and its fits train and score on each distinct decision once."""

from __future__ import annotations

import math

import numpy as np

from metairl_engine import FitConfig, Trajectory
from metairl_engine.demos import state_action_pairs
from metairl_engine.fit import _Problem
from metairl_engine.holdout import distinct_steps, repeats_its_decisions, split_steps
from metairl_engine.results import TaskData
from metairl_engine.sim.benchmark import goal_tasks
from metairl_engine.sim.objectworld import make_objectworld


def loop(actions: list[int], *, laps: int) -> Trajectory:
    """A walk round states 0 … n − 1 ``laps`` times, taking ``actions[k]`` in state k on every lap."""
    n = len(actions)
    return Trajectory.of([k % n for k in range(n * laps + 1)], actions * laps)


def test_a_demonstrator_that_repeats_its_action_wherever_it_returns_is_deterministic() -> None:
    assert repeats_its_decisions([[loop([k % 5 for k in range(12)], laps=3)]])


def test_a_demonstrator_that_changes_its_action_on_a_return_is_not() -> None:
    first, second = [k % 5 for k in range(12)], [(k + 1) % 5 for k in range(12)]
    varied = Trajectory.of(list(range(12)) * 2 + [0], first + second)
    assert not repeats_its_decisions([[varied]])


def test_too_few_returns_cannot_show_a_deterministic_demonstrator() -> None:
    assert not repeats_its_decisions([[loop([0, 1, 2, 3, 4], laps=3)]])  # 5 states revisited, < 10


def test_distinct_steps_keep_each_decision_once_in_order_of_first_occurrence() -> None:
    states, actions = np.array([3, 1, 3, 1, 2, 3]), np.array([0, 4, 0, 4, 1, 2])
    kept_states, kept_actions = distinct_steps(states, actions)
    assert kept_states.tolist() == [3, 1, 2, 3]
    assert kept_actions.tolist() == [0, 4, 1, 2]


def test_folds_of_distinct_steps_hold_out_each_decision_in_one_fold_only() -> None:
    demos = [[loop([k % 5 for k in range(20)], laps=4)]]  # 80 steps, 20 distinct
    folds = [split_steps(demos, fraction=0.25, seed=1, fold=k, distinct=True) for k in range(4)]
    for train, held in folds:
        assert len(train) + len(held) == 20
        assert not set(train.states.tolist()) & set(held.states.tolist())
    assert sorted(np.concatenate([held.states for _, held in folds]).tolist()) == list(range(20))


def test_fits_count_an_optimal_demonstrators_repeated_steps_once_and_a_boltzmann_demonstrators_all() -> None:
    world, _ = make_objectworld(seed=3, size=8, n_objects=6)
    for rationality, distinct in ((math.inf, True), (1.0, False)):
        sims = goal_tasks(world, n_tasks=3, n_demos=4, seed=0, goal_bonus=10.0, rationality=rationality)
        tasks = [TaskData(world.mdp, s.trajectories, s.name) for s in sims]
        assert repeats_its_decisions([t.trajectories for t in tasks]) is distinct
        problem = _Problem(tasks, FitConfig(ensemble=1, stay_at_ends=False))  # the demonstrator's own steps
        steps = [np.stack(state_action_pairs(t.trajectories)) for t in tasks]
        expected = sum(np.unique(s, axis=1).shape[1] if distinct else s.shape[1] for s in steps)
        assert len(problem.train) + len(problem.held) == expected
