"""The tabular MaxEnt reference solver: exact gradient, recovery of a known reward, result shape, cancellation."""

from __future__ import annotations

import numpy as np
import pytest

from metairl_engine import FitConfig
from metairl_engine.errors import Cancelled
from metairl_engine.fit import fit
from metairl_engine.maxent import _TaskObjective
from metairl_engine.metrics import pearson
from metairl_engine.results import Progress
from tests.engine.helpers import small_grid, soft_demos, task
from tests.engine.test_fit import bump_reward


def test_objective_gradient_matches_central_differences() -> None:
    mdp = small_grid(size=4)
    demos = soft_demos(mdp, bump_reward(4), starts=np.arange(16), length=5, seed=0)
    objective = _TaskObjective(task(mdp, demos), FitConfig(method="maxent", confidence=2.0), should_stop=None)
    r = np.random.default_rng(0).normal(size=16)
    _, grad = objective(r)
    eps = 1e-3
    numeric = [
        (objective(r + eps * np.eye(16)[k])[0] - objective(r - eps * np.eye(16)[k])[0]) / (2 * eps)
        for k in range(16)
    ]
    np.testing.assert_allclose(grad, numeric, rtol=1e-3, atol=1e-4)


def test_recovers_a_known_reward_and_returns_the_fit_result_shape() -> None:
    mdp = small_grid(size=5)
    reward = bump_reward(5)
    demos = soft_demos(mdp, reward, starts=np.repeat(np.arange(25), 20), length=5, seed=0, confidence=3.0)
    seen: list[Progress] = []
    result = fit(
        [task(mdp, demos), task(mdp, demos[:100])],
        FitConfig(method="maxent", confidence=3.0),
        progress=seen.append,
    )
    assert pearson(result.rewards[0], reward) >= 0.95
    assert result.rewards.shape == (2, 25) and result.policies.shape == (2, 25, mdp.n_actions)
    np.testing.assert_allclose(result.baseline, result.rewards.mean(axis=0), atol=1e-6)
    assert [p.step for p in seen] == list(range(1, len(seen) + 1)) and result.history == seen


def test_should_stop_cancels_maxent() -> None:
    mdp = small_grid(size=3)
    demos = soft_demos(mdp, bump_reward(3), starts=np.arange(9), length=3, seed=0)
    with pytest.raises(Cancelled):
        fit([task(mdp, demos)], FitConfig(method="maxent"), should_stop=lambda: True)
