"""An MDP without features: the data choose between the networks on coordinates and the tabular solver (probed
each task alone, answered with shared rewards), by the likelihood of held-out whole demonstrations, and the
result says which."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from metairl_engine import MDP, FitConfig, TaskData
from metairl_engine.demos import Trajectory
from metairl_engine.fit import fit, tabular_choice_applies
from metairl_engine.holdout import demonstration_folds, demonstration_nlls, predicts_better
from metairl_engine.memory import fit_memory
from metairl_engine.planning import stay_actions
from metairl_engine.sim.terrain import make_tasks, make_world

QUICK = FitConfig(hidden=(16,), max_steps=40, ensemble=2)


def walk(*states: int) -> Trajectory:
    """A demonstration through ``states``, taking action 0 at each but the last."""
    return Trajectory(np.array(states, dtype=np.int64), np.zeros(len(states) - 1, dtype=np.int64))


def featureless(mdp: MDP) -> MDP:
    """The MDP uploaded with its layout but without features."""
    return replace(mdp, features=None)


def terrain_tasks(*, n_demos: int = 3) -> list[TaskData]:
    """Three goal tasks on a small terrain without features: a cost smooth in the place."""
    world = make_world(size=8, n_hills=2, seed=0)
    mdp = featureless(world.mdp)
    return [
        TaskData(mdp, s.trajectories[:n_demos], s.name)
        for s in make_tasks(world, n_tasks=3, n_demos=3, seed=1)
    ]


def test_every_demonstration_is_held_out_once_in_as_many_folds_as_the_fewest_allow_up_to_three() -> None:
    demos = [[walk(i, i) for i in range(n)] for n in (3, 10, 4)]
    folds = demonstration_folds(demos)
    held = [[[int(tr.states[0]) for tr in h] for h in fold_held] for _, fold_held in folds]
    assert held == [[[0], [0, 3, 6, 9], [0, 3]], [[1], [1, 4, 7], [1]], [[2], [2, 5, 8], [2]]]
    for train, fold_held in folds:
        for kept, out, task in zip(train, fold_held, demos, strict=True):
            assert sorted(int(tr.states[0]) for tr in kept + out) == list(range(len(task)))
    two = demonstration_folds([[walk(0, 0), walk(1, 1)], [walk(i, i) for i in range(5)]])
    held_two = [[int(tr.states[0]) for tr in h] for _, fold_held in two for h in fold_held]
    assert held_two == [[0], [0, 2, 4], [1], [1, 3]]


def test_a_held_out_demonstration_that_ended_by_choice_is_scored_with_its_stay_and_training_ones_as_given() -> (
    None
):
    # lengths 2, 1, 1: the two shorter ones stopped by choice (at state 1), the longest ran to the end
    task = [walk(0, 1, 2), walk(0, 1), walk(3, 1)]
    stay = np.array([-1, 4, 4, -1])  # state s's stay action (none at 0 and 3)
    folds = demonstration_folds([task], stays=[stay])
    held = [(fold_held[0][0].states.tolist(), fold_held[0][0].actions.tolist()) for _, fold_held in folds]
    assert held == [([0, 1, 2], [0, 0]), ([0, 1, 1], [0, 4]), ([3, 1, 1], [0, 4])]
    for (train, _), (plain, _) in zip(folds, demonstration_folds([task]), strict=True):
        assert [tr.states.tolist() for tr in train[0]] == [tr.states.tolist() for tr in plain[0]]


def test_demonstration_nlls_sum_each_held_out_demonstration_s_steps_under_its_task_s_policy() -> None:
    policies = np.array([[[0.5, 0.5], [0.25, 0.75]], [[0.1, 0.9], [1.0, 0.0]]])  # (T=2, S=2, A=2)
    totals = demonstration_nlls(policies, [[walk(0, 1, 1)], [walk(1, 0), walk(0, 0)]])
    np.testing.assert_allclose(totals, [-np.log(0.5) - np.log(0.25), -np.log(1.0), -np.log(0.1)])


def test_the_solver_is_chosen_when_it_predicts_the_held_out_demonstrations_better_by_any_margin() -> None:
    incumbent = np.array([20.0, 20.0, 20.0, 20.0])
    assert predicts_better(incumbent + np.array([-1.0, 1.0, -1.0, 0.99]), incumbent)
    tie = incumbent + np.array([-1.0, 1.0, -1.0, 1.0])
    assert not predicts_better(tie, incumbent)  # a tie keeps the networks
    assert not predicts_better(incumbent + 0.01, incumbent)


def test_the_choice_is_the_result_s_config_and_refitting_with_it_gives_the_same_result() -> None:
    tasks = terrain_tasks()
    chosen = fit(tasks, QUICK)
    assert chosen.config.method == "shared_maxent" or chosen.config.tabular_choice is False
    again = fit(tasks, chosen.config)
    np.testing.assert_array_equal(chosen.rewards, again.rewards)


def test_the_choice_reports_progress_over_its_seven_fits() -> None:
    seen: list[tuple[int, int]] = []
    fit(terrain_tasks(), replace(QUICK, patience=0), progress=lambda p: seen.append((p.step, p.max_steps)))
    assert {m for _, m in seen} == {280} and seen[-1][0] == 280  # 3 folds × (networks, solver), the refit
    assert all(b >= a for (a, _), (b, _) in itertools.pairwise(seen))


@pytest.mark.parametrize(
    "change",
    [
        {"tabular_choice": False},
        {"sharing": "none"},
        {"holdout_fraction": 0.0},
        {"method": "maxent"},
        {"method": "shared_maxent"},
    ],
)
def test_no_choice_where_the_config_asks_for_one_model(change: dict[str, object]) -> None:
    assert tabular_choice_applies(terrain_tasks(), QUICK)
    assert not tabular_choice_applies(terrain_tasks(), replace(QUICK, **change))  # type: ignore[arg-type]


def test_no_choice_with_features_or_a_single_demonstration_per_task() -> None:
    world = make_world(size=8, n_hills=2, seed=0)
    sims = make_tasks(world, n_tasks=2, n_demos=3, seed=1)
    assert not tabular_choice_applies([TaskData(world.mdp, s.trajectories) for s in sims], QUICK)
    assert not tabular_choice_applies(terrain_tasks(n_demos=1), QUICK)
    steps: list[int] = []
    result = fit(terrain_tasks(n_demos=1), QUICK, progress=lambda p: steps.append(p.max_steps))
    assert set(steps) == {QUICK.max_steps} and result.config.tabular_choice is True


def test_features_that_only_say_where_a_state_is_count_as_none_without_a_layout() -> None:
    world = make_world(size=8, n_hills=2, seed=0)
    sims = make_tasks(world, n_tasks=2, n_demos=3, seed=1)
    assert world.mdp.features is not None and world.mdp.layout is not None
    on_grid = [TaskData(world.mdp, s.trajectories) for s in sims]
    assert not tabular_choice_applies(on_grid, QUICK)  # a grid keeps its coordinates as features
    cells = np.arange(world.mdp.n_states)
    xy = np.stack([cells % 8, cells // 8], axis=1).astype(np.float32)
    uploaded = replace(world.mdp, features=xy, layout=None)
    assert tabular_choice_applies([TaskData(uploaded, s.trajectories) for s in sims], QUICK)
    height = replace(world.mdp, features=np.concatenate([xy, world.cost[:, None]], axis=1), layout=None)
    assert not tabular_choice_applies([TaskData(height, s.trajectories) for s in sims], QUICK)


def test_a_cost_smooth_in_the_place_stays_with_the_networks() -> None:
    """A terrain's cost carries over between neighbouring places, as coordinates assume: the networks predict
    the held-out demonstrations better than a solver that leaves unvisited states at 0."""
    result = fit(terrain_tasks(), FitConfig(max_steps=200))
    assert result.config.method == "meta_irl" and result.config.tabular_choice is False


@pytest.mark.parametrize("solver_wins", [True, False])
def test_the_model_that_predicts_the_held_out_demonstrations_is_refitted_on_all(
    monkeypatch: pytest.MonkeyPatch, solver_wins: bool
) -> None:
    compared: list[np.ndarray] = []

    def verdict(challenger: np.ndarray, incumbent: np.ndarray) -> bool:
        compared.append(challenger)
        assert len(challenger) == len(incumbent) == 9  # every demonstration of the 3 tasks, under both
        return solver_wins

    monkeypatch.setattr("metairl_engine.fit.predicts_better", verdict)
    tasks = terrain_tasks()
    result = fit(tasks, QUICK)
    # The probe is the solver that extrapolates nothing: each task alone, on the demonstrations a fold keeps.
    probed = []
    stays = [stay_actions(t.mdp) for t in tasks]  # each held-out demonstration scored as the fits count it
    for train, held in demonstration_folds([t.trajectories for t in tasks], stays=stays):
        kept = [replace(t, trajectories=d) for t, d in zip(tasks, train, strict=True)]
        probed.append(demonstration_nlls(fit(kept, replace(QUICK, method="maxent")).policies, held))
    assert len(compared) == 1
    np.testing.assert_array_equal(compared[0], np.concatenate(probed))
    expected = replace(QUICK, method="shared_maxent") if solver_wins else replace(QUICK, tabular_choice=False)
    assert result.config == expected
    np.testing.assert_array_equal(result.rewards, fit(tasks, expected).rewards)


def test_the_memory_estimate_of_a_choice_is_the_larger_of_its_two_models() -> None:
    sizes = {"n_tasks": 2, "n_states": 400, "n_actions": 4, "n_features": None, "n_steps": 200, "n_mdps": 1}
    both = fit_memory(FitConfig(), **sizes).total  # type: ignore[arg-type]
    networks = fit_memory(FitConfig(tabular_choice=False), **sizes).total  # type: ignore[arg-type]
    solver = fit_memory(FitConfig(method="shared_maxent"), **sizes).total  # type: ignore[arg-type]
    assert both == max(networks, solver)
