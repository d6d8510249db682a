"""The reward's spread across the ensemble's members and the demonstrations' evidence per state."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from metairl_engine import FitConfig, Trajectory
from metairl_engine.evidence import NEXT_TO_VISITED, VISITED, evidence, tasks_evidence
from metairl_engine.fit import TaskData, fit, member_spread
from metairl_engine.grids import grid_mdp

SIZE = 6
MDP = grid_mdp(width=SIZE, height=SIZE, moves=4, gamma=0.9)
RIGHT, UP = 0, 1  # action indices of a 4-move grid: E, N, W, S


def walk(start: int, actions: list[int]) -> Trajectory:
    """The trajectory of ``actions`` from ``start`` on `MDP`, with its final state."""
    assert MDP.next_state is not None
    states = [start]
    for a in actions:
        states.append(int(MDP.next_state[states[-1], a]))
    return Trajectory.of(states, actions)


LEFT_COLUMNS = [walk(y * SIZE, [UP] * (SIZE - 1 - y)) for y in range(0, 3)] + [
    walk(y * SIZE + 1, [UP] * (SIZE - 1 - y)) for y in range(0, 3)
]
"""Demonstrations that stay in the two leftmost columns (walk up from the bottom rows)."""


@pytest.fixture(scope="module")
def spread() -> tuple[np.ndarray, np.ndarray]:
    """A 4-member fit of one task whose demonstrations cover only the left columns: (reward_spread[0],
    baseline_spread)."""
    result = fit([TaskData(MDP, LEFT_COLUMNS)], FitConfig(ensemble=4, max_steps=150, seed=0))
    assert result.reward_spread is not None and result.baseline_spread is not None
    return result.reward_spread[0], result.baseline_spread


def test_spread_is_finite_per_state_and_nonnegative(spread: tuple[np.ndarray, np.ndarray]) -> None:
    for values in spread:
        assert values.shape == (MDP.n_states,) and values.dtype == np.float32
        assert np.all(np.isfinite(values)) and np.all(values >= 0) and values.max() > 0


def test_one_member_has_no_spread() -> None:
    result = fit([TaskData(MDP, LEFT_COLUMNS)], FitConfig(ensemble=1, max_steps=5))
    assert result.reward_spread is None and result.baseline_spread is None


def test_evidence_marks_visits_their_neighbours_and_nothing_else() -> None:
    one = [walk(0, [RIGHT, RIGHT])]  # cells (0,0), (1,0), (2,0) of the bottom row
    seen = evidence(MDP, one)
    assert seen.shape == (MDP.n_states,)
    assert set(np.flatnonzero(seen == VISITED)) == {0, 1, 2}
    assert set(np.flatnonzero(seen == NEXT_TO_VISITED)) == {3, SIZE, SIZE + 1, SIZE + 2}
    assert np.count_nonzero(seen) == 7


def test_the_baselines_evidence_is_the_most_any_task_gives() -> None:
    a, b = [walk(0, [RIGHT])], [walk(SIZE * SIZE - 1, [])]
    base, per_task = tasks_evidence([TaskData(MDP, a), TaskData(MDP, b)])
    np.testing.assert_array_equal(base, np.maximum(per_task[0], per_task[1]))
    assert base[0] == VISITED and base[SIZE * SIZE - 1] == VISITED and per_task[0][SIZE * SIZE - 1] == 0


def test_members_that_differ_only_in_level_and_scale_have_no_spread() -> None:
    shape = torch.randn(1, 3, 20, generator=torch.Generator().manual_seed(0))
    members = torch.cat([shape, 2.0 * shape + 1.0, 0.5 * shape - 3.0, -shape])  # (4 members, 3 tasks, 20)
    spread = member_spread(members)
    assert spread is not None and spread.shape == (3, 20)
    np.testing.assert_allclose(spread, 0.0, atol=1e-5)


def test_the_spread_is_on_the_scale_of_the_members_mean() -> None:
    members = torch.randn(4, 2, 30, generator=torch.Generator().manual_seed(1))
    spread, scaled = member_spread(members), member_spread(10.0 * members + 5.0)
    assert spread is not None and scaled is not None and spread.max() > 0.1
    np.testing.assert_allclose(scaled, 10.0 * spread, rtol=1e-4, atol=1e-5)
