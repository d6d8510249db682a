"""Validation of MDPs, demonstrations and configs: every error names where and what."""

import warnings
from typing import Any

import numpy as np
import pytest

from metairl_engine import MDP, FitConfig, InvalidInput, Layout, TaskData, Trajectory, validate_trajectories
from metairl_engine.fit import fit


def pointers(exc: pytest.ExceptionInfo[InvalidInput]) -> list[str]:
    return [i.pointer for i in exc.value.issues]


def chain(n: int = 4) -> MDP:
    """A line of n states; action 0 stays, action 1 moves right (the last state stays)."""
    nxt = np.stack([np.arange(n), np.minimum(np.arange(n) + 1, n - 1)], axis=1)
    return MDP.build(gamma=0.9, next_state=nxt)


def test_deterministic_mdp_infers_sizes() -> None:
    m = chain(5)
    assert (m.n_states, m.n_actions, m.is_deterministic, m.n_features) == (5, 2, True, 5)


@pytest.mark.parametrize("gamma", [1.0, -0.1, float("nan")])
def test_gamma_outside_unit_interval_is_rejected(gamma: float) -> None:
    with pytest.raises(InvalidInput) as exc:
        MDP.build(gamma=gamma, next_state=[[0]])
    assert pointers(exc) == ["/gamma"]


def test_next_state_out_of_range_names_state_and_action() -> None:
    with pytest.raises(InvalidInput) as exc:
        MDP.build(gamma=0.9, next_state=[[0, 1], [1, 7]])
    assert pointers(exc) == ["/transitions/next_state/1/1"]
    assert "outside 0..1" in str(exc.value)


def test_sparse_probabilities_must_sum_to_one_per_state_action() -> None:
    with pytest.raises(InvalidInput) as exc:
        MDP.build(
            gamma=0.9, n_states=2, n_actions=1, s=[0, 0, 1], a=[0, 0, 0], next=[0, 1, 1], p=[0.5, 0.4, 1]
        )
    assert pointers(exc) == ["/transitions/p"]
    assert "state 0, action 0 sum to 0.9" in str(exc.value)


def test_sparse_missing_state_action_is_reported() -> None:
    with pytest.raises(InvalidInput) as exc:
        MDP.build(gamma=0.9, n_states=2, n_actions=1, s=[0], a=[0], next=[1], p=[1.0])
    assert "no transitions given" in str(exc.value)


def test_features_with_nan_point_at_the_cell() -> None:
    with pytest.raises(InvalidInput) as exc:
        MDP.build(gamma=0.9, next_state=[[0], [1]], features=[[0.0, 1.0], [np.nan, 0.0]])
    assert pointers(exc) == ["/features/1/0"]


def test_a_feature_past_float32s_range_is_refused_as_such_without_a_warning() -> None:
    with warnings.catch_warnings(), pytest.raises(InvalidInput) as exc:
        warnings.simplefilter("error")  # numpy's overflow in the cast would otherwise be a RuntimeWarning
        MDP.build(gamma=0.9, next_state=[[0], [1]], features=[[0.0, 1e39], [0.0, 0.0]])
    assert pointers(exc) == ["/features/0/1"] and "float32's range" in str(exc.value)


def test_layout_must_cover_all_states() -> None:
    with pytest.raises(InvalidInput) as exc:
        MDP.build(gamma=0.9, next_state=[[0], [1], [2]], layout=Layout(width=2, height=2))
    assert pointers(exc) == ["/layout"]


def test_impossible_step_names_trajectory_and_step() -> None:
    m = chain(4)
    good = Trajectory.of([0, 1, 2], [1, 1])
    bad = Trajectory.of([0, 1, 3], [1, 1])
    validate_trajectories(m, [good])
    with pytest.raises(InvalidInput) as exc:
        validate_trajectories(m, [good, bad])
    assert pointers(exc) == ["/trajectories/1/states/2"]
    assert "trajectory 1 step 1" in str(exc.value)


def test_out_of_range_action_names_trajectory_and_step() -> None:
    with pytest.raises(InvalidInput) as exc:
        validate_trajectories(chain(4), [Trajectory.of([0, 1], [1, 5])])
    assert pointers(exc) == ["/trajectories/0/actions/1"]


def test_sparse_mdp_step_check_uses_positive_probabilities() -> None:
    m = MDP.build(
        gamma=0.9,
        n_states=3,
        n_actions=1,
        s=[0, 0, 1, 2],
        a=[0, 0, 0, 0],
        next=[1, 2, 2, 2],
        p=[0.5, 0.5, 1, 1],
    )
    validate_trajectories(m, [Trajectory.of([0, 2, 2], [0, 0])])
    with pytest.raises(InvalidInput):
        validate_trajectories(m, [Trajectory.of([1, 0], [0])])


def test_config_rejects_bad_values_and_unknown_keys() -> None:
    with pytest.raises(InvalidInput) as exc:
        FitConfig(learning_rate=0.0, max_steps=0)
    assert pointers(exc) == ["/config/learning_rate", "/config/max_steps"]
    with pytest.raises(InvalidInput) as exc:
        FitConfig.from_dict({"sharing_wieght": 1.0})
    assert pointers(exc) == ["/config/sharing_wieght"]
    assert FitConfig.from_dict({"hidden": [4, 2]}).hidden == (4, 2)


@pytest.mark.parametrize(
    ("settings", "words"),
    [
        ({"method": "MAXENT"}, "must be one of 'meta_irl', 'maxent', 'shared_maxent'"),
        ({"sharing": "bogus"}, "must be one of"),
        ({"shrink_deviations": "no"}, "true or false"),
        ({"max_steps": "100"}, "an integer"),
        ({"max_steps": 1.5}, "an integer"),
        ({"max_steps": True}, "an integer"),
        ({"tolerance": float("inf")}, "finite"),
        ({"learning_rate": "0.01"}, "finite"),
        ({"hidden": 100}, "list of integers"),
    ],
)
def test_a_setting_of_the_wrong_type_is_invalid_input_naming_it(settings: dict, words: str) -> None:
    """A notebook's typo must not run another method, nor reach a comparison that raises TypeError."""
    with pytest.raises(InvalidInput) as exc:
        FitConfig(**settings)
    assert pointers(exc) == [f"/config/{next(iter(settings))}"] and words in str(exc.value)


def test_a_list_where_a_tuple_is_meant_is_the_same_setting() -> None:
    listed: dict[str, Any] = {"hidden": [100, 50, 25]}  # as a notebook writes it
    assert FitConfig(**listed) == FitConfig() and hash(FitConfig(**listed))


def test_a_trajectory_of_fractional_states_is_refused_rather_than_truncated_to_other_states() -> None:
    with pytest.raises(InvalidInput) as exc:
        Trajectory.of(np.array([0.0, 0.5, 1.7]), [0, 1])  # a notebook's floats
    assert pointers(exc) == ["/states/1"] and "0.5 is not a whole number" in str(exc.value)
    whole = Trajectory.of(np.array([0.0, 1.0]), np.array([1.0]))  # whole floats are the indices they name
    assert whole.states.tolist() == [0, 1]
    with pytest.raises(InvalidInput) as exc:
        validate_trajectories(chain(), [Trajectory(np.array([0.0, 1.0]), np.array([1.0]))])
    assert pointers(exc) == ["/trajectories/0"] and "integer arrays" in str(exc.value)


def test_fit_called_with_the_wrong_kinds_of_argument_says_which() -> None:
    """A notebook's slips: a dict for the config, one task for a list, a tuple for a task, a device torch
    does not know, no MDP, trajectories as a generator or built from lists without `Trajectory.of`:
    `InvalidInput` naming the argument, not an AttributeError deep in the fit."""
    task = TaskData(mdp=chain(), trajectories=[Trajectory.of([0, 1], [1])], name="t")
    for args, kwargs, pointer in (
        (([task], {"max_steps": 3}), {}, "/config"),
        ((task,), {}, "/tasks"),
        (([(task.mdp, task.trajectories)],), {}, "/tasks/0"),
        (([TaskData(mdp=chain(), trajectories=[([0, 1], [1])], name="t")],), {}, "/tasks/0/trajectories"),  # type: ignore[list-item]
        (([task],), {"device": "tpu"}, "/device"),
        (([TaskData(mdp=None, trajectories=task.trajectories)],), {}, "/tasks/0/mdp"),  # type: ignore[arg-type]
        (([TaskData(chain(), (t for t in task.trajectories))],), {}, "/tasks/0/trajectories"),  # type: ignore[arg-type]
        (([TaskData(mdp=chain(), trajectories=[Trajectory([0, 1], [1])])],), {}, "/tasks/0/trajectories/0"),  # type: ignore[arg-type]
    ):
        with pytest.raises(InvalidInput) as exc:
            fit(*args, **kwargs)  # type: ignore[arg-type]
        assert pointers(exc) == [pointer]


def test_numpy_scalars_are_the_python_numbers_they_hold() -> None:
    """A notebook's arithmetic gives numpy scalars: sizes, gamma and settings take them as plain numbers."""
    mdp = MDP.build(gamma=np.float32(0.5), n_states=np.int64(2), next_state=np.array([[1], [0]]))  # type: ignore[arg-type]
    assert (mdp.gamma, mdp.n_states) == (0.5, 2) and type(mdp.gamma) is float
    settings: dict[str, Any] = {"max_steps": np.int64(10), "learning_rate": np.float64(0.01)}
    config = FitConfig(**settings, hidden=[np.int64(8), 4])  # type: ignore[arg-type]
    assert config == FitConfig(max_steps=10, learning_rate=0.01, hidden=(8, 4))
    assert type(config.max_steps) is int and all(type(h) is int for h in config.hidden)
    with pytest.raises(InvalidInput):
        FitConfig(**{"max_steps": np.float64(2.5)})  # type: ignore[arg-type]  # a fraction, not a step count


def test_an_mdp_made_without_build_is_checked_before_a_fit_blames_its_settings() -> None:
    """``MDP(...)`` checks nothing: NaN features or a table of the wrong shape are InvalidInput naming the task's
    MDP, not a diverged loss."""
    good = chain()
    nan_features = MDP(
        n_states=good.n_states,
        n_actions=good.n_actions,
        gamma=0.9,
        next_state=good.next_state,
        features=np.full((good.n_states, 2), np.nan, dtype=np.float32),
    )
    short_table = MDP(
        n_states=good.n_states + 1, n_actions=good.n_actions, gamma=0.9, next_state=good.next_state
    )
    for mdp, pointer in ((nan_features, "/tasks/0/mdp/features"), (short_table, "/tasks/0/mdp/next_state")):
        with pytest.raises(InvalidInput) as exc:
            fit([TaskData(mdp, [Trajectory.of([0, 1], [1])])], FitConfig(max_steps=3))
        assert pointer in pointers(exc) and "MDP.build" in str(exc.value)


def test_a_trajectory_of_nested_states_is_refused_where_it_is_built() -> None:
    with pytest.raises(InvalidInput) as exc:
        Trajectory.of(np.array([[0, 1], [1, 2]]), [1, 1])
    assert pointers(exc) == ["/states"] and "(2, 2)" in str(exc.value)
