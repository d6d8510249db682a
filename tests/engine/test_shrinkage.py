"""Task rewards are shrunk towards the baseline, and their deviation from it made sparse, as far as held-out steps
allow."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

import metairl_engine.fit as fit_module
import metairl_engine.shrinkage as shrinkage_module
from metairl_engine import FitConfig
from metairl_engine.backups import QRows
from metairl_engine.fit import fit
from metairl_engine.planning import transition_matrix, value_iteration
from metairl_engine.results import FitResult, TaskData
from metairl_engine.shrinkage import (
    SHRINKAGE,
    SPARSITY,
    one_standard_error_choice,
    optimal_q,
    sparse_deviation,
)
from tests.engine.helpers import as_sparse, small_grid, soft_demos, task

CONFIG = FitConfig(hidden=(16,), max_steps=120, ensemble=2, holdout_fraction=0.3)


def _same_reward_tasks(n_tasks: int = 4) -> list[TaskData]:
    """Tasks on a 5×5 grid that all follow one reward (a slope towards a corner), two short demonstrations
    each: whatever a task learns beyond the shared reward is noise."""
    mdp = small_grid(size=5)
    assert mdp.features is not None
    reward = mdp.features.sum(axis=1).astype(np.float64)
    return [
        task(mdp, soft_demos(mdp, reward, starts=np.array([0, 12]), length=5, seed=i, confidence=3.0))
        for i in range(n_tasks)
    ]


def test_tasks_that_share_one_reward_are_pulled_to_the_baseline_by_the_chosen_candidate() -> None:
    tasks = _same_reward_tasks()
    one = replace(CONFIG, ensemble=1)  # one member: the result is that member's candidate itself
    shrunk = fit(tasks, one)
    learned = fit(tasks, replace(one, shrink_deviations=False))
    assert (learned.shrinkage, learned.sparsity) == (1.0, 0.0)
    assert shrunk.shrinkage in SHRINKAGE and shrunk.sparsity in (*SPARSITY, 1.0)
    assert (shrunk.shrinkage, shrunk.sparsity) != (1.0, 0.0)
    # The same networks (the choice comes after the fit): baseline + λ·S_q(task reward − baseline).
    np.testing.assert_allclose(shrunk.baseline, learned.baseline)
    deviation = torch.from_numpy(learned.rewards - learned.baseline)
    kept = sparse_deviation(deviation, shrunk.sparsity if shrunk.shrinkage else 0.0).numpy()
    np.testing.assert_allclose(shrunk.rewards, learned.baseline + shrunk.shrinkage * kept, atol=1e-5)
    # Values and policies are those of the shrunk rewards, not of the networks.
    assert not np.allclose(shrunk.values, learned.values, atol=1e-3)
    np.testing.assert_allclose(shrunk.policies.sum(axis=-1), 1.0, atol=1e-5)


def test_a_sparse_deviation_zeroes_the_smallest_share_and_keeps_the_order_of_the_rest() -> None:
    deviation = torch.tensor([[0.1, -0.2, 0.3, -0.4, 2.0, -0.05, 0.0, 0.15, -1.0, 0.5]])
    kept = sparse_deviation(deviation, 0.5)
    assert int((kept == 0).sum()) == 5
    large = deviation.abs() > torch.quantile(deviation.abs(), 0.5)
    assert torch.equal(kept[large].sign(), deviation[large].sign())
    assert torch.equal(kept[large].abs().argsort(), deviation[large].abs().argsort())
    assert torch.equal(sparse_deviation(deviation, 0.0), deviation)


def test_the_sparsest_candidate_keeps_a_goal_and_zeroes_the_wiggles_around_it() -> None:
    # What a goal task adds on a few hundred states: one large bump, and small noise everywhere else.
    rng = np.random.default_rng(0)
    deviation = torch.from_numpy(rng.normal(0.0, 0.05, size=(1, 400)))
    deviation[0, 123] = 3.0
    kept = sparse_deviation(deviation, max(SPARSITY))
    assert int((kept != 0).sum()) <= 2 and float(kept[0, 123]) > 2.5
    assert int((sparse_deviation(deviation, 0.95) != 0).sum()) >= 19  # the next candidate keeps 20 states


def test_the_choice_is_the_candidate_within_one_standard_error_that_departs_least_from_the_baseline() -> None:
    noise = torch.tensor([-1.0, 1.0] * 50)  # per-step NLLs with a standard error of about 0.1
    nll = {
        (1.0, 0.0): 1.0 + noise,
        (0.5, 0.0): 0.95 + noise,  # the best
        (1.0, 0.9): 1.02 + noise,
        (0.5, 0.9): 1.04 + noise,
        (0.25, 0.0): 1.2 + noise,  # departs least but the baseline's, worse by two standard errors
        (0.0, 0.0): 1.5 + noise,  # the baseline alone: departs by nothing, far worse
    }
    # Σ|λ·S_q(d)|: S_0.9 keeps a fifth of the deviation's L1 norm here
    departure = {(lam, q): lam * (1.0 if q == 0.0 else 0.2) for lam, q in nll}
    assert one_standard_error_choice(nll, departure) == (0.5, 0.9)
    nll[1.0, 0.9] = 0.94 + noise  # a new best changes nothing: (0.5, 0.9) is still within one standard error
    assert one_standard_error_choice(nll, departure) == (0.5, 0.9)
    nll[0.0, 0.0] = 1.0 + noise
    assert one_standard_error_choice(nll, departure) == (0.0, 0.0)


def test_each_candidate_departs_from_the_baseline_by_the_l1_norm_of_its_kept_deviation(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    mdp = small_grid(size=4)
    every = np.arange(mdp.n_states)
    rows = QRows([mdp, mdp], np.repeat([0, 1], mdp.n_states), np.tile(every, 2), columns=every, n_columns=16)
    gamma = torch.full((2,), mdp.gamma, dtype=torch.float32)
    generator = torch.Generator().manual_seed(0)
    baseline = torch.randn(2, mdp.n_states, generator=generator)
    rewards = baseline + torch.randn(2, mdp.n_states, generator=generator)
    q, values = optimal_q(rows, rewards, gamma, values=torch.zeros(2, mdp.n_states), kind="max", bgi_k=10.0)
    seen: dict[tuple[float, float], float] = {}

    def record(nll: object, departure: dict[tuple[float, float], float]) -> tuple[float, float]:
        seen.update(departure)
        return (0.0, 0.0)

    monkeypatch.setattr(shrinkage_module, "one_standard_error_choice", record)
    shrunk = shrinkage_module.shrink_deviations(
        rows, rewards, baseline, gamma, q=q, values=values, score=lambda q: q[:, 0, 0], kind="max", bgi_k=10.0
    )
    assert set(seen) == {(lam, q) for lam in SHRINKAGE for q in SPARSITY if lam > 0} | {(0.0, 0.0)}
    for (lam, sparsity), size in seen.items():
        kept = sparse_deviation(rewards - baseline, sparsity)
        assert size == pytest.approx(lam * float(kept.abs().sum()), rel=1e-5)
    torch.testing.assert_close(shrunk.rewards, baseline)  # the candidate chosen is what is returned


def test_without_a_baseline_or_a_hold_out_the_task_rewards_are_kept_as_learned() -> None:
    tasks = _same_reward_tasks(n_tasks=2)
    for config in (replace(CONFIG, sharing="none"), replace(CONFIG, holdout_fraction=0.0)):
        on = fit(tasks, config)
        off = fit(tasks, replace(config, shrink_deviations=False))
        assert (on.shrinkage, on.sparsity) == (1.0, 0.0)
        np.testing.assert_array_equal(on.rewards, off.rewards)


def test_value_iteration_on_the_networks_rows_matches_the_reference_planner() -> None:
    rng = np.random.default_rng(3)
    for mdp in (small_grid(size=4), as_sparse(small_grid(size=4))):
        rewards = rng.normal(size=(2, mdp.n_states))
        every = np.arange(mdp.n_states)
        rows = QRows(
            [mdp, mdp],
            np.repeat([0, 1], mdp.n_states),
            np.tile(every, 2),
            columns=every,
            n_columns=mdp.n_states,
        )
        gamma = torch.full((2,), mdp.gamma, dtype=torch.float32)
        q, _ = optimal_q(
            rows,
            torch.from_numpy(rewards).float(),
            gamma,
            values=torch.zeros(2, mdp.n_states, dtype=torch.float32),
            kind="max",
            bgi_k=10.0,
        )
        for i in range(2):
            reference = value_iteration(transition_matrix(mdp), rewards[i], gamma=mdp.gamma, backup="max").q
            np.testing.assert_allclose(q[i].numpy(), reference, atol=1e-2)


def test_the_chosen_share_survives_saving_the_result(tmp_path: Path) -> None:
    result = fit(_same_reward_tasks(n_tasks=2), replace(CONFIG, max_steps=20))
    path = tmp_path / "result.npz"
    result.save(path)
    loaded = FitResult.load(path)
    assert (loaded.shrinkage, loaded.sparsity) == (result.shrinkage, result.sparsity)


def test_a_fit_with_more_task_states_than_the_budget_keeps_the_task_rewards_as_learned(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    tasks = _same_reward_tasks(n_tasks=2)
    n_task_states = 2 * CONFIG.ensemble * tasks[0].mdp.n_states
    monkeypatch.setattr(fit_module, "SHRINK_BUDGET", n_task_states - 1)
    over = fit(tasks, CONFIG)
    assert (over.shrinkage, over.sparsity) == (1.0, 0.0)
    monkeypatch.setattr(fit_module, "SHRINK_BUDGET", n_task_states)
    within = fit(tasks, CONFIG)
    assert (within.shrinkage, within.sparsity) != (1.0, 0.0)
