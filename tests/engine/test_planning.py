"""Planning on a known reward: the soft backup's row-wise log-sum-exp, and rewards planned together."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import logsumexp

from metairl_engine.planning import PlanBackup, row_logsumexp, value_iteration


def test_row_logsumexp_is_scipys_on_wide_ranges_and_infinite_entries() -> None:
    rng = np.random.default_rng(0)
    wide = rng.normal(size=(64, 9)) * 300.0  # exp overflows without the shift
    edges = np.array([[-np.inf, -np.inf], [1e300, 1e300], [0.0, -np.inf], [-745.0, -746.0]])
    for x in (wide, edges):
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # a row of −∞ has log 0
            expected, found = logsumexp(x, axis=1), row_logsumexp(x)
        np.testing.assert_allclose(found, expected, rtol=1e-13)


@pytest.mark.parametrize("backup", ["soft", "max"])
def test_rewards_planned_together_get_the_values_and_policies_each_gets_alone(backup: PlanBackup) -> None:
    rng = np.random.default_rng(1)
    n_states, n_actions = 40, 4
    targets = rng.integers(0, n_states, size=n_states * n_actions)
    transitions = sp.csr_matrix(
        (np.ones(n_states * n_actions), (np.arange(n_states * n_actions), targets)),
        shape=(n_states * n_actions, n_states),
    )
    rewards = rng.normal(size=(n_states, 3)) * np.array([1.0, 5.0, 0.1])  # converging at different speeds
    together = value_iteration(transitions, rewards, gamma=0.9, backup=backup)
    assert together.value.shape == (n_states, 3) and together.policy.shape == (n_states, n_actions, 3)
    for t in range(3):
        alone = value_iteration(transitions, rewards[:, t], gamma=0.9, backup=backup)
        np.testing.assert_array_equal(together.value[:, t], alone.value)
        np.testing.assert_array_equal(together.policy[:, :, t], alone.policy)
