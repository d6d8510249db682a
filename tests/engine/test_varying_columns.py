"""Feature columns the same on every state are left out of the networks' inputs: they carry nothing."""

from __future__ import annotations

import numpy as np

from metairl_engine import FitConfig
from metairl_engine.fit import _Problem, fit, varying_columns
from tests.engine.helpers import goal_tasks_with_features, small_grid

CONFIG = FitConfig(hidden=(8,), max_steps=40, ensemble=2)


def test_constant_feature_columns_leave_the_fit_exactly_as_without_them() -> None:
    places = small_grid(size=5).features
    assert places is not None
    padded = np.concatenate(
        [np.ones((25, 3)), places[:, :1], np.zeros((25, 1)), places[:, 1:]], axis=1
    ).astype(np.float32)
    plain, with_constants = (
        fit(goal_tasks_with_features(places), CONFIG),
        fit(goal_tasks_with_features(padded), CONFIG),
    )
    np.testing.assert_array_equal(plain.rewards, with_constants.rewards)
    np.testing.assert_array_equal(plain.baseline, with_constants.baseline)


def test_the_networks_see_only_the_varying_columns_plus_the_task_coordinates() -> None:
    rng = np.random.default_rng(0)
    features = np.concatenate([np.ones((25, 4)), rng.integers(0, 2, size=(25, 3))], axis=1)
    problem = _Problem(goal_tasks_with_features(features.astype(np.float32)), CONFIG)
    assert problem.base_features is not None and problem.base_features.shape[1] == 3
    assert problem.features is not None and problem.features.shape[1] == 3 + 10  # x, y and their waves


def test_features_that_never_vary_are_kept_whole() -> None:
    assert varying_columns(np.ones((6, 3))).tolist() == [0, 1, 2]
    assert varying_columns(np.array([[1.0, 0.0, 2.0], [1.0, 1.0, 2.0]])).tolist() == [1]
