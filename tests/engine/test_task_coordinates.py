"""Task networks see the states' coordinates besides features that cannot tell places apart; the baseline does not."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from metairl_engine import FitConfig
from metairl_engine.fit import _Problem, fit
from metairl_engine.results import TaskData
from tests.engine.helpers import as_sparse, small_grid, soft_demos, task

GOAL = 18  # cell (3, 3) of the 5×5 grid


def _goal_tasks(*, features: np.ndarray | None) -> list[TaskData]:
    """Two tasks on a 5×5 grid whose state features are ``features``: one heads for GOAL, one for cell 0."""
    mdp = replace(small_grid(size=5), features=features)
    out = []
    for goal in (GOAL, 0):
        reward = np.zeros(25)
        reward[goal] = 1.0
        starts = np.arange(25)
        out.append(task(mdp, soft_demos(mdp, reward, starts=starts, length=6, seed=goal, confidence=5.0)))
    return out


def test_a_goal_features_cannot_single_out_is_learned_at_its_cell_from_the_coordinates() -> None:
    # One feature, the same on every state: only the coordinates can say where the goal is.
    tasks = _goal_tasks(features=np.ones((25, 1), dtype=np.float32))
    config = FitConfig(hidden=(16,), max_steps=150, holdout_fraction=0.0, ensemble=1)
    with_places = fit(tasks, config)
    blind = fit(tasks, replace(config, task_coordinates=False))
    for reward, goal in zip(with_places.rewards, (GOAL, 0), strict=True):
        assert reward[goal] > np.quantile(reward, 0.8)  # among the highest fifth: the goal is found
    assert np.ptp(blind.rewards[0]) < 1e-3 < np.ptp(with_places.rewards[0])
    assert np.ptp(with_places.baseline) < 1e-3  # the baseline sees the (constant) features alone


def test_features_that_are_the_coordinates_are_not_given_twice() -> None:
    grid = small_grid(size=5)  # features: the layout's normalised x, y
    problem = _Problem(_goal_tasks(features=grid.features), FitConfig(ensemble=1))
    assert problem.features is not None and problem.features.shape[1] == 2
    assert problem.base_features is problem.features


def test_a_stochastic_mdp_fits_without_a_hold_out() -> None:
    tasks = [replace(t, mdp=as_sparse(t.mdp)) for t in _goal_tasks(features=small_grid(size=5).features)]
    result = fit(tasks, FitConfig(hidden=(8,), max_steps=5, holdout_fraction=0.0, ensemble=1))
    assert len(result.history) == 5 and np.isfinite(result.rewards).all()
