"""Where a demonstration stops by choice it counts one more step, the MDP's stay action there: a
length-limited or recorded demonstration is left as it is, and the fit trains on the added steps."""

from __future__ import annotations

import numpy as np

from metairl_engine import FitConfig, Trajectory
from metairl_engine.demos import chosen_ends, ended_by_choice, with_stays_at_ends
from metairl_engine.fit import _Problem, fit
from metairl_engine.grids import grid_mdp
from metairl_engine.planning import stay_actions
from metairl_engine.results import TaskData
from metairl_engine.sim.benchmark import goal_tasks
from metairl_engine.sim.objectworld import make_objectworld
from tests.engine.helpers import small_grid

STAY = 4
"""A plain grid's stay action with 4 moves (E, N, W, S, then stay)."""


def test_a_grids_stay_action_keeps_every_state_and_a_velocity_grid_has_one_only_against_a_wall() -> None:
    grid = small_grid()
    stays = stay_actions(grid)
    assert grid.next_state is not None
    assert (grid.next_state[np.arange(25), stays] == np.arange(25)).all()  # on the edge, a move into the wall
    assert (stays.reshape(5, 5)[1:-1, 1:-1] == STAY).all()
    velocity = stay_actions(grid_mdp(width=6, height=6, moves=8, velocity=True, gamma=0.9))
    inner = velocity.reshape(8, 6, 6)[:, 1:-1, 1:-1]
    assert (inner == -1).all()
    assert (velocity >= 0).any()  # moving into a wall in the direction one already moves


def test_with_slip_the_stay_action_is_the_one_most_likely_to_remain() -> None:
    slipped = grid_mdp(width=5, height=5, moves=4, stay=True, slip=0.3, gamma=0.9)
    centre = 2 * 5 + 2
    assert stay_actions(slipped)[centre] == STAY


def test_demonstrations_cut_at_one_length_at_separate_states_did_not_end_by_choice() -> None:
    cut = [Trajectory.of([0, 1, 2], [0, 0]), Trajectory.of([10, 11, 12], [0, 0])]
    assert not ended_by_choice(cut).any()


def test_equally_long_demonstrations_ending_at_one_state_were_cut_by_a_step_limit() -> None:
    cut = [Trajectory.of([0, 1, 2], [0, 0]), Trajectory.of([10, 11, 2], [0, 0])]
    assert not ended_by_choice(cut).any()


def test_a_shorter_demonstration_or_one_ending_where_another_ends_stopped_by_choice() -> None:
    demos = [
        Trajectory.of([0, 1, 2, 3], [0, 0, 0]),  # the longest, ending alone: cut
        Trajectory.of([5, 6], [0]),  # shorter: stopped
        Trajectory.of([20, 21, 22, 6], [0, 0, 0]),  # as long as the longest, but ends where another does
        Trajectory.of([7], [0]),  # shorter, but no final state: nothing known of its end
    ]
    assert ended_by_choice(demos).tolist() == [False, True, True, False]
    assert chosen_ends(demos).tolist() == [6]  # the two stops at 6 name one state


def test_a_stopped_demonstration_gains_the_stay_step_at_its_end_and_the_others_are_kept() -> None:
    mdp = small_grid()
    demos = [Trajectory.of([0, 1, 2, 3], [0, 0, 0]), Trajectory.of([10, 11], [0])]
    cut, stopped = with_stays_at_ends(demos, stay_actions(mdp))
    assert cut is demos[0]
    assert stopped.states.tolist() == [10, 11, 11]
    assert stopped.actions.tolist() == [0, STAY]


def test_where_no_action_stays_a_stopped_demonstration_is_kept_as_it_is() -> None:
    no_stay = np.full(25, -1)
    demos = [Trajectory.of([0, 1, 2, 3], [0, 0, 0]), Trajectory.of([10, 11], [0])]
    assert with_stays_at_ends(demos, no_stay)[1] is demos[1]


def test_the_fit_trains_on_one_stay_step_per_stopped_demonstration_unless_told_not_to() -> None:
    mdp = small_grid()
    to_goal = [
        Trajectory.of([0, 1, 2, 7, 12], [0, 0, 1, 1]),
        Trajectory.of([17, 12], [3]),
    ]
    tasks = [TaskData(mdp, to_goal, "reach the centre")]
    steps = {
        on: _Problem(tasks, FitConfig(stay_at_ends=on, ensemble=1, holdout_fraction=0.0)).train
        for on in (True, False)
    }
    assert len(steps[True]) == len(steps[False]) + 2
    added = (steps[True].states == 12) & (steps[True].actions == STAY)
    assert added.sum() == 2


def test_at_gamma_0_99_every_tasks_reward_peaks_at_its_goal() -> None:
    # without the stays, one task's reward on each of these worlds peaks beside its goal (ranks 12 and 1)
    for seed in (1, 3):
        world, _ = make_objectworld(seed=seed, size=8, n_objects=6, gamma=0.99)
        sims = goal_tasks(world, n_tasks=3, n_demos=3, seed=seed, goal_bonus=10.0)
        result = fit([TaskData(world.mdp, s.trajectories, s.name) for s in sims], FitConfig())
        assert [int(np.argmax(r)) for r in result.rewards] == [s.goal for s in sims]
