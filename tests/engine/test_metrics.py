"""Reward metrics: correlations, EPIC-style distance, key states, likelihood, expected value difference."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from metairl_engine.metrics import (
    accuracy,
    epic_distance,
    expected_value_difference,
    key_states,
    nll,
    pearson,
    spearman,
)
from tests.engine.helpers import small_grid
from tests.engine.test_fit import bump_reward


def test_pearson_and_spearman_of_known_vectors() -> None:
    a = np.array([1.0, 2.0, 3.0, 4.0])
    assert pearson(a, 2 * a + 1) == pytest.approx(1.0)
    assert pearson(a, -a) == pytest.approx(-1.0)
    assert spearman(a, a**3) == pytest.approx(1.0) and pearson(a, a**3) < 1.0
    assert pearson(
        a, np.array([1.0, 0.0, 0.0, 5.0]), mask=np.array([True, True, True, False])
    ) == pytest.approx(-0.8660254, abs=1e-6)


def test_constant_vectors_correlate_with_nothing() -> None:
    assert pearson(np.ones(5), np.arange(5.0)) == 0.0
    assert spearman(np.ones(5), np.arange(5.0)) == 0.0


def test_epic_distance_is_zero_for_affine_copies_and_one_for_opposites() -> None:
    r = np.random.default_rng(0).normal(size=50)
    assert epic_distance(r, 3 * r - 7) == pytest.approx(0.0, abs=1e-6)
    assert epic_distance(r, -r) == pytest.approx(1.0)
    weights = np.r_[np.ones(25), np.zeros(25)]
    other = np.r_[r[:25], -r[25:]]
    assert epic_distance(r, other, weights=weights) == pytest.approx(0.0, abs=1e-6)
    assert epic_distance(r, other) > 0.3
    with pytest.raises(ValueError):
        epic_distance(r, r, weights=-weights)


def test_key_states_are_the_largest_departures_from_the_baseline() -> None:
    baseline = np.zeros(6)
    task = np.array([0.1, -3.0, 0.0, 2.0, 0.5, 0.0])
    assert key_states(task, baseline, top=3).tolist() == [1, 3, 4]
    assert key_states(task, baseline, top=99).tolist() == [1, 3, 4, 0]  # not the two equal states
    assert key_states(baseline, baseline, top=3).tolist() == []


def test_nll_and_accuracy_of_a_policy() -> None:
    policy = np.array([[0.5, 0.5], [0.9, 0.1]])
    states, actions = np.array([0, 1, 1]), np.array([1, 0, 1])
    assert nll(policy, states, actions) == pytest.approx(-(np.log(0.5) + np.log(0.9) + np.log(0.1)) / 3)
    assert accuracy(policy, states, actions) == pytest.approx(1 / 3)


def test_expected_value_difference_is_zero_for_the_true_reward_and_positive_for_its_opposite() -> None:
    mdp = small_grid(size=4)
    reward = bump_reward(4)
    assert expected_value_difference(mdp, reward, 2 * reward + 1) == pytest.approx(0.0, abs=1e-5)
    assert expected_value_difference(mdp, reward, -reward) > 0.5


def test_metrics_import_without_torch() -> None:
    code = "import sys, metairl_engine, metairl_engine.metrics, metairl_engine.sim.terrain; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_the_fit_is_an_attribute_of_the_package_imported_with_torch_on_first_use() -> None:
    code = (
        "import sys, metairl_engine as m; before = 'torch' in sys.modules; f = m.fit; "
        "print(before, 'torch' in sys.modules, callable(f), hasattr(m, 'nothing'))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "True", "True", "False"]


def test_a_reward_of_the_wrong_length_for_the_evd_says_which() -> None:
    mdp = small_grid(size=4)
    reward = bump_reward(4)
    for wrong in (reward[:-1], np.stack([reward, reward])):
        with pytest.raises(ValueError, match=r"learned_reward has shape .*; the MDP's states need \(16,\)"):
            expected_value_difference(mdp, reward, wrong)


def test_correlations_of_finite_values_near_the_float64_limits_are_finite() -> None:
    huge = np.array([1e308] * 12 + [-1e308] * 13)
    ramp = np.arange(25.0)
    for a, b in ((huge, ramp), (ramp * 1e-310, huge), (huge, -huge)):
        r, rho = pearson(a, b), spearman(a, b)
        assert np.isfinite(r) and np.isfinite(rho), (a, b)
        expected = np.corrcoef(a / np.abs(a).max(), b / np.abs(b).max())[0, 1]
        assert abs(r - expected) < 1e-9
    assert pearson(huge, -huge) == -1.0 and np.isfinite(epic_distance(huge, ramp))
