"""Ensembles and the stopping signal: members train side by side exactly as alone, folds are disjoint,
the automatic size follows the budget, and the calibrated held-out NLL ignores the scale of Q."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from metairl_engine import FitConfig, Trajectory
from metairl_engine.config import ENSEMBLE_BUDGET, MAX_AUTO_MEMBERS, ensemble_size
from metairl_engine.fit import _Problem, calibrated_nll, fit, gradient_step
from metairl_engine.holdout import split_steps
from metairl_engine.networks import StackedMLP, fourier_features
from tests.engine.helpers import goal_tasks_with_features
from tests.engine.test_fit import terrain_tasks


def test_each_ensemble_member_gets_the_gradient_it_would_get_alone() -> None:
    tasks, _ = terrain_tasks(seed=0, n_tasks=3, n_demos=3)
    pair, alone = _Problem(tasks, FitConfig(ensemble=2)), _Problem(tasks, FitConfig(ensemble=1))
    gen = torch.Generator().manual_seed(0)
    vr = StackedMLP(n_members=6, n_inputs=2, hidden=(8, 4), tabular=False, generator=gen)
    base = StackedMLP(n_members=2, n_inputs=2, hidden=(8, 4), tabular=False, generator=gen)
    vr1 = StackedMLP(n_members=3, n_inputs=2, hidden=(8, 4), tabular=False, generator=gen)
    base1 = StackedMLP(n_members=1, n_inputs=2, hidden=(8, 4), tabular=False, generator=gen)
    with torch.no_grad():  # member 0 of the pair starts where the lone fit starts
        for p, q in zip(
            [*vr.parameters(), *base.parameters()], [*vr1.parameters(), *base1.parameters()], strict=True
        ):
            p[: q.shape[0]] = q
    gradient_step(pair, vr, base, FitConfig(ensemble=2))
    gradient_step(alone, vr1, base1, FitConfig(ensemble=1))
    for p, q in zip(
        [*vr.parameters(), *base.parameters()], [*vr1.parameters(), *base1.parameters()], strict=True
    ):
        assert p.grad is not None and q.grad is not None
        # The pair's loss is the mean over twice as many networks: its gradient is half the lone one.
        assert torch.allclose(2 * p.grad[: q.shape[0]], q.grad, atol=1e-6)


def test_folds_of_one_seed_hold_out_disjoint_steps() -> None:
    chain = Trajectory.of(list(range(21)), [0] * 20)  # 20 steps, each with its own state
    held = [split_steps([[chain]], fraction=0.25, seed=3, fold=k)[1].states for k in range(4)]
    assert [len(h) for h in held] == [5, 5, 5, 5]
    assert len(set(np.concatenate(held).tolist())) == 20


def test_automatic_ensemble_size_shrinks_as_problems_grow() -> None:
    auto = FitConfig()
    assert ensemble_size(auto, n_tasks=8, n_states=256) == 4
    assert ensemble_size(auto, n_tasks=16, n_states=576) == 3
    assert ensemble_size(auto, n_tasks=16, n_states=80_000) == 1
    assert ensemble_size(FitConfig(ensemble=2), n_tasks=16, n_states=80_000) == 2


@pytest.mark.parametrize(("budget", "members"), [(ENSEMBLE_BUDGET, MAX_AUTO_MEMBERS), (100, 2), (50, 1)])
def test_the_result_of_an_automatic_ensemble_states_its_members_and_refits_alike(
    monkeypatch: pytest.MonkeyPatch, budget: int, members: int
) -> None:
    """``ensemble`` 0 leaves K to the fit (`ensemble_size`, 2 tasks × 25 states here): the result's config
    says the K fitted, so refitting with it is the same fit."""
    monkeypatch.setattr("metairl_engine.config.ENSEMBLE_BUDGET", budget)
    tasks = goal_tasks_with_features(np.random.default_rng(0).normal(size=(25, 3)).astype(np.float32))
    auto = FitConfig(hidden=(8,), max_steps=5)
    result = fit(tasks, auto)
    assert result.config == replace(auto, ensemble=members)
    assert (result.reward_spread is None) == (members == 1)  # a spread needs two members or more
    again = fit(tasks, result.config)
    assert again.config == result.config
    np.testing.assert_array_equal(again.rewards, result.rewards)


def test_an_ensemble_fit_returns_one_reward_per_task() -> None:
    tasks, _ = terrain_tasks(seed=2, n_tasks=3, n_demos=2)
    result = fit(tasks, FitConfig(ensemble=3, max_steps=20))
    assert result.rewards.shape == (3, 64) and result.baseline.shape == (64,)
    assert np.allclose(result.policies.sum(axis=-1), 1.0, atol=1e-5)


def test_calibrated_held_out_nll_ignores_the_scale_of_q() -> None:
    gen = torch.Generator().manual_seed(0)
    q = torch.randn(50, 4, generator=gen)
    actions = q.argmax(dim=1)
    actions[::3] = torch.randint(0, 4, (17,), generator=gen)
    groups = [torch.arange(25), torch.arange(25, 50)]
    once = calibrated_nll(q, actions, confidence=1.0, groups=groups)
    twice = calibrated_nll(2 * q, actions, confidence=1.0, groups=groups)
    for a, b in zip(once, twice, strict=True):
        assert torch.allclose(a.mean(), b.mean(), atol=1e-6)
    plain = torch.nn.functional.cross_entropy(4 * q, actions)
    assert float(twice[0].mean() + twice[1].mean()) / 2 <= float(plain) + 1e-6


def test_fourier_features_keep_the_raw_columns_and_add_two_waves_per_octave() -> None:
    features = np.linspace(0, 1, 10, dtype=np.float32).reshape(5, 2)
    assert fourier_features(features, octaves=0) is features
    encoded = fourier_features(features, octaves=3)
    assert encoded.shape == (5, 2 + 2 * 2 * 3) and encoded.dtype == np.float32
    assert np.array_equal(encoded[:, :2], features)
