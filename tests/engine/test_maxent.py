"""The tabular MaxEnt solvers, each task alone and with shared rewards: exact gradients, recovery of a known
reward, result shape, pooling across tasks, cancellation."""

from __future__ import annotations

import numpy as np
import pytest

from metairl_engine import FitConfig
from metairl_engine.errors import Cancelled
from metairl_engine.fit import fit
from metairl_engine.maxent import _SharedObjective, _TaskObjective
from metairl_engine.metrics import pearson
from metairl_engine.planning import transition_matrix
from metairl_engine.results import Progress, TaskData
from metairl_engine.sim.terrain import SimTask, tasks_with_goals
from tests.engine.helpers import small_grid, soft_demos, task
from tests.engine.test_fit import bump_reward


def test_objective_gradient_matches_central_differences() -> None:
    mdp = small_grid(size=4)
    demos = soft_demos(mdp, bump_reward(4), starts=np.arange(16), length=5, seed=0)
    config = FitConfig(method="maxent", confidence=2.0)
    objective = _TaskObjective(task(mdp, demos), transition_matrix(mdp), config, should_stop=None)
    assert_gradient_matches(objective, np.random.default_rng(0).normal(size=16))


def assert_gradient_matches(objective: _TaskObjective | _SharedObjective, x: np.ndarray) -> None:
    """The objective's gradient at x equals its central differences (steps of 10⁻², well above what value
    iteration's tolerance of 10⁻⁶ moves the objective by)."""
    _, grad = objective(x)
    eps = 1e-2
    steps = eps * np.eye(len(x))
    numeric = [(objective(x + step)[0] - objective(x - step)[0]) / (2 * eps) for step in steps]
    np.testing.assert_allclose(grad, numeric, rtol=1e-3, atol=1e-3)


def goal_tasks(*, n_tasks: int, n_demos: int, seed: int = 0) -> tuple[list[SimTask], np.ndarray]:
    """Goal tasks on a seeded 5×5 grid sharing one bump reward (each plus 3 at its goal), and that reward."""
    mdp = small_grid(size=5)
    reward = bump_reward(5)
    sims = tasks_with_goals(
        mdp,
        reward,
        size=5,
        n_tasks=n_tasks,
        n_demos=n_demos,
        seed=seed,
        goal_bonus=3.0,
        rationality=3.0,
        max_length=None,
    )
    return sims, reward


def as_tasks(sims: list[SimTask]) -> list[TaskData]:
    """The simulated tasks as the fit reads them."""
    return [TaskData(small_grid(size=5), s.trajectories, s.name) for s in sims]


def test_shared_objective_gradient_matches_central_differences() -> None:
    tasks = as_tasks(goal_tasks(n_tasks=3, n_demos=4)[0])
    config = FitConfig(method="shared_maxent", confidence=2.0)
    p = transition_matrix(tasks[0].mdp)
    shared = _SharedObjective(tasks, [_TaskObjective(t, p, config, should_stop=None) for t in tasks])
    assert len(shared.bonus_state) > 0  # the goals the demonstrations stopped at
    assert_gradient_matches(shared, np.random.default_rng(0).normal(size=len(shared.start())))


def test_shared_task_rewards_depart_from_the_baseline_only_where_their_demonstrations_stopped() -> None:
    sims, _ = goal_tasks(n_tasks=3, n_demos=4)
    result = fit(as_tasks(sims), FitConfig(method="shared_maxent"))
    for sim, reward in zip(sims, result.rewards, strict=True):
        departs = np.flatnonzero(~np.isclose(reward, result.baseline))
        ends = {int(t.states[-1]) for t in sim.trajectories}
        assert sim.goal in departs and set(departs) <= ends
    assert not np.allclose(result.baseline, result.rewards.mean(axis=0))  # a reward of its own, not a mean


def test_each_goal_is_carried_by_its_tasks_bonus_not_the_shared_reward() -> None:
    """Where a task stopped, the shared reward stands near its median: another task's policy is not drawn to a
    goal that is not its own (equal ridges would give the shared reward 37 … 51 % of each goal here)."""
    sims, _ = goal_tasks(n_tasks=3, n_demos=4, seed=2)
    result = fit(as_tasks(sims), FitConfig(method="shared_maxent"))
    for sim, reward in zip(sims, result.rewards, strict=True):
        shared = result.baseline[sim.goal] - np.median(result.baseline)
        assert abs(shared) < 0.1 * (reward[sim.goal] - np.median(result.baseline))


def test_sharing_gives_each_task_the_others_evidence() -> None:
    """With two demonstrations per task, each task's reward (its goal left out) is nearer the shared truth when
    every task's demonstrations inform it than from its own alone."""
    sims, reward = goal_tasks(n_tasks=6, n_demos=2, seed=1)
    tasks = as_tasks(sims)
    off_goal = [np.arange(25) != s.goal for s in sims]

    def accuracy(method: str) -> float:
        rewards = fit(tasks, FitConfig(method=method)).rewards  # type: ignore[arg-type]
        return float(np.mean([pearson(r, reward, mask=m) for r, m in zip(rewards, off_goal, strict=True)]))

    assert accuracy("shared_maxent") > accuracy("maxent") + 0.1


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


@pytest.mark.parametrize("method", ["maxent", "shared_maxent"])
def test_should_stop_cancels_the_tabular_methods(method: str) -> None:
    mdp = small_grid(size=3)
    demos = soft_demos(mdp, bump_reward(3), starts=np.arange(9), length=3, seed=0)
    with pytest.raises(Cancelled):
        fit([task(mdp, demos)], FitConfig(method=method), should_stop=lambda: True)  # type: ignore[arg-type]
