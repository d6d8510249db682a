"""Task networks see the states' coordinates besides features that cannot tell places apart, or the place alone;
the baseline sees the features."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from metairl_engine import FitConfig
from metairl_engine.coordinates import TASK_COORDINATE_COLUMNS
from metairl_engine.fit import _Problem, fit, place_wins
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


def test_the_place_alone_replaces_the_features_in_the_task_networks_inputs_only() -> None:
    features = np.random.default_rng(0).random((25, 3)).astype(np.float32)
    tasks = _goal_tasks(features=features)
    both = _Problem(tasks, FitConfig(ensemble=1))
    place = _Problem(tasks, FitConfig(ensemble=1, task_features="no"))
    assert both.features is not None and place.features is not None
    assert both.features.shape[1] == 3 + TASK_COORDINATE_COLUMNS
    assert place.features.shape[1] == TASK_COORDINATE_COLUMNS
    assert torch.equal(place.features, both.features[:, 3:])
    assert place.base_features is not None and both.base_features is not None
    assert torch.equal(place.base_features, both.base_features)  # the baseline sees the features either way


def test_auto_keeps_the_inputs_whose_held_out_steps_it_predicts_and_says_which() -> None:
    tasks = _goal_tasks(features=np.random.default_rng(0).random((25, 3)).astype(np.float32))
    config = FitConfig(hidden=(16,), max_steps=60, ensemble=2)
    chosen = fit(tasks, replace(config, task_features="auto"))
    assert chosen.config.task_features in ("yes", "no")
    again = fit(tasks, replace(config, task_features=chosen.config.task_features))
    np.testing.assert_array_equal(chosen.rewards, again.rewards)  # the choice's own fit, bit for bit


def test_auto_fits_once_where_there_is_no_choice() -> None:
    steps: list[int] = []
    grid = small_grid(size=5)  # features that are the coordinates: the place adds nothing
    config = FitConfig(hidden=(8,), max_steps=20, ensemble=1, task_features="auto")
    result = fit(_goal_tasks(features=grid.features), config, progress=lambda p: steps.append(p.max_steps))
    assert result.config.task_features == "yes" and set(steps) == {20}
    one_task = _goal_tasks(features=np.random.default_rng(1).random((25, 3)).astype(np.float32))[:1]
    assert fit(one_task, config).config.task_features == "yes"


def test_auto_reports_progress_over_both_fits() -> None:
    tasks = _goal_tasks(features=np.random.default_rng(2).random((25, 3)).astype(np.float32))
    seen: list[tuple[int, int]] = []
    config = FitConfig(hidden=(8,), max_steps=20, ensemble=1, patience=0, task_features="auto")
    fit(tasks, config, progress=lambda p: seen.append((p.step, p.max_steps)))
    assert seen == [(s, 40) for s in range(1, 41)]


def test_the_place_wins_only_by_more_than_one_standard_error() -> None:
    with_features = torch.tensor([1.0, 2.0, 1.0, 2.0])
    standard_error = float(with_features.std()) / 2
    assert place_wins(with_features, with_features - 1.01 * standard_error)
    assert not place_wins(with_features, with_features - 0.99 * standard_error)
    assert not place_wins(with_features, with_features + 0.1)
