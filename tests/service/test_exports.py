"""Downloads of reward, value and policy arrays: npy, csv and json round trips, coordinates, names, ETags."""

import io
import json
import re

import numpy as np
import pytest

from metairl_engine.mdp import Layout
from service.files.exports import (
    download_filename,
    etag_for,
    grid_coordinates,
    summary,
    to_csv,
    to_json,
    to_npy,
)

LAYOUT = Layout(width=3, height=2, channels=2)
AWKWARD = np.array([0.1, -0.0, 1e-30, 3.0e38, -1.2345679e8, 1 / 3, 7.0, -2.5e-7, 0.3, 1e-45, 5.0, -1.0])
SHA = "ab" * 32


def reward(n: int = 12) -> np.ndarray:
    return np.random.default_rng(n).normal(size=n).astype(np.float32)


def test_grid_coordinates_invert_the_layout_numbering() -> None:
    x, y, channel = grid_coordinates(np.arange(12), LAYOUT)
    assert x.tolist() == [0, 1, 2] * 4
    assert y.tolist() == [0, 0, 0, 1, 1, 1] * 2
    assert channel.tolist() == [0] * 6 + [1] * 6
    big = Layout(width=100, height=100, channels=8)
    states = np.random.default_rng(0).integers(0, 80_000, size=(50, 4))
    x, y, channel = grid_coordinates(states, big)
    assert x.shape == states.shape
    assert ((channel * 100 + y) * 100 + x == states).all()
    assert x.max() < 100 and y.max() < 100 and channel.max() < 8


@pytest.mark.parametrize("states", [np.array([12]), np.array([-1]), np.array([0.5])])
def test_grid_coordinates_refuse_states_outside_the_layout(states: np.ndarray) -> None:
    with pytest.raises(ValueError):
        grid_coordinates(states, LAYOUT)


@pytest.mark.parametrize("values", [AWKWARD, reward().reshape(4, 3), np.arange(5)])
def test_npy_round_trips_exactly_as_float32(values: np.ndarray) -> None:
    loaded = np.load(io.BytesIO(to_npy(values)), allow_pickle=False)
    assert loaded.dtype == np.float32 and loaded.shape == values.shape
    assert np.array_equal(loaded, values.astype(np.float32))
    assert np.signbit(loaded).tolist() == np.signbit(values.astype(np.float32)).tolist()


def test_csv_without_layout_has_state_and_quantity_and_reads_back_exactly() -> None:
    text = to_csv(AWKWARD, layout=None, quantity="reward")
    lines = text.splitlines()
    assert lines[0] == "state,reward" and len(lines) == 13
    assert lines[1].startswith("0,") and lines[12].startswith("11,")
    table = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1)
    assert table[:, 0].tolist() == list(range(12))
    assert np.array_equal(table[:, 1].astype(np.float32), AWKWARD.astype(np.float32))


def test_csv_with_layout_adds_x_y_channel() -> None:
    values = reward()
    text = to_csv(values, layout=LAYOUT, quantity="value")
    assert text.splitlines()[0] == "state,x,y,channel,value"
    table = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1)
    state, x, y, channel = (table[:, k].astype(int) for k in range(4))
    assert ((channel * LAYOUT.height + y) * LAYOUT.width + x == state).all()
    assert table[7, 1:4].tolist() == [1, 0, 1]
    assert np.array_equal(table[:, 4].astype(np.float32), values)


def test_csv_of_a_policy_has_one_column_per_action() -> None:
    policy = np.random.default_rng(1).dirichlet(np.ones(4), size=12).astype(np.float32)
    text = to_csv(policy, layout=LAYOUT, quantity="policy")
    assert text.splitlines()[0] == "state,x,y,channel,a0,a1,a2,a3"
    table = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1)
    assert table.shape == (12, 8)
    assert np.array_equal(table[:, 4:].astype(np.float32), policy)


@pytest.mark.parametrize(
    ("values", "layout", "quantity"),
    [
        (reward(10), LAYOUT, "reward"),
        (reward(), None, "reward,x"),
        (reward(), None, "Reward"),
        (np.array([1.0, np.nan]), None, "reward"),
        (np.zeros((2, 2, 2)), None, "reward"),
        (np.zeros(0), None, "reward"),
    ],
)
def test_csv_refuses_bad_input(values: np.ndarray, layout: Layout | None, quantity: str) -> None:
    with pytest.raises(ValueError):
        to_csv(values, layout=layout, quantity=quantity)


def test_json_of_a_reward_follows_the_contract_and_reads_back_exactly() -> None:
    doc = json.loads(to_json(AWKWARD, reward_id='rwd_"x"', quantity="reward"))
    assert doc["reward_id"] == 'rwd_"x"' and doc["quantity"] == "reward" and doc["n_states"] == 12
    assert np.array_equal(np.array(doc["values"], dtype=np.float32), AWKWARD.astype(np.float32))
    assert "n_actions" not in doc


def test_json_of_a_policy_is_a_list_of_rows() -> None:
    policy = np.random.default_rng(2).dirichlet(np.ones(3), size=5).astype(np.float32)
    doc = json.loads(to_json(policy, reward_id="rwd_1", quantity="policy"))
    assert doc["n_states"] == 5 and doc["n_actions"] == 3 and len(doc["values"]) == 5
    assert np.array_equal(np.array(doc["values"], dtype=np.float32), policy)


def test_json_refuses_non_finite_values() -> None:
    with pytest.raises(ValueError, match="finite"):
        to_json(np.array([0.0, np.inf]), reward_id="rwd_1", quantity="reward")


SAFE_NAME = re.compile(r"[a-z0-9-]+_[a-z0-9-]+_[a-z0-9-]+\.[a-z0-9]+")


@pytest.mark.parametrize(
    ("demonstrator", "task", "quantity", "ext", "expected"),
    [
        ("Patient 3", "Forward", "reward", "csv", "patient-3_forward_reward.csv"),
        ("patient-3", None, "reward", "npy", "patient-3_baseline_reward.npy"),
        ("Pátient_3", "walk (left)", "value", ".PNG", "patient-3_walk-left_value.png"),
        ('../../etc/"x"\r\n', "a/b\\c", "policy", "json", "etc-x_a-b-c_policy.json"),
        ("机器人", "", "reward", "csv", "demonstrator_task_reward.csv"),
        ("R" * 100, "t", "reward", "csv", "r" * 40 + "_t_reward.csv"),
    ],
)
def test_download_filenames_are_readable_and_safe(
    demonstrator: str, task: str | None, quantity: str, ext: str, expected: str
) -> None:
    name = download_filename(demonstrator=demonstrator, task=task, quantity=quantity, ext=ext)
    assert name == expected
    assert SAFE_NAME.fullmatch(name)


@pytest.mark.parametrize(("quantity", "ext"), [("reward", "c/sv"), ("reward", ""), ("../x", "csv")])
def test_download_filename_refuses_unsafe_quantity_or_extension(quantity: str, ext: str) -> None:
    with pytest.raises(ValueError):
        download_filename(demonstrator="p", task=None, quantity=quantity, ext=ext)


def test_etags_are_quoted_stable_and_differ_per_variant() -> None:
    tag = etag_for(SHA, "csv", "reward")
    assert re.fullmatch(r'"[0-9a-f]{32}"', tag)
    assert tag == etag_for(SHA.upper(), "csv", "reward")
    others = {
        etag_for(SHA),
        etag_for(SHA, "csv", "value"),
        etag_for(SHA, "png", "reward", 100),
        etag_for(SHA, "png", "reward", 200),
        etag_for("cd" * 32, "csv", "reward"),
        etag_for(SHA, "csv,reward"),
    }
    assert len(others) == 6 and tag not in others
    with pytest.raises(ValueError):
        etag_for("not-a-digest", "csv")


def test_summary_of_a_reward() -> None:
    out = summary(np.array([1.0, -2.0, 4.0, 1.0], dtype=np.float32))
    assert out == {
        "min": -2.0,
        "max": 4.0,
        "mean": 1.0,
        "std": pytest.approx(np.sqrt(4.5)),
        "argmax_state": 2,
        "argmin_state": 1,
    }
    assert all(type(out[k]) is float for k in ("min", "max", "mean", "std"))
    assert type(out["argmax_state"]) is int
    with pytest.raises(ValueError):
        summary(np.ones((3, 2)))
