"""Comparisons (docs/api.md, "Comparisons and key states"): metrics against scipy on all and visited states, across jobs and demonstrators,
field-naming 422s, the comparison matrix and key states. Results are stored without a worker (`fitted_job`)."""

from __future__ import annotations

import importlib.util
import io
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from PIL import Image
from scipy.stats import pearsonr, spearmanr

from metairl_client import Client
from service.files.images import matrix_pixel_size, matrix_png
from tests.service.helpers import created, fitted_job, make_task
from tests.service.test_rewards import N_STATES, RIGHT, UP, WIDTH, grid, random_rewards

ROOT = Path(__file__).resolve().parents[2]
UP_LEFT = [{"states": [0, 5, 10, 15], "actions": [1, 1, 1]}]
"""The second session walks up the left column instead of the middle one."""


@pytest.fixture
def mdp(client: TestClient, auth: dict[str, str]) -> dict[str, Any]:
    """The 5×4 grid both sessions use."""
    return grid(client, auth)


@pytest.fixture
def sessions(
    app: FastAPI, client: TestClient, auth: dict[str, str], mdp: dict[str, Any]
) -> list[dict[str, Any]]:
    """One patient's two sessions as two demonstrators, each a succeeded job over 'walk right' and 'walk up'."""
    out = []
    for seed, name in enumerate(("patient 1, unstimulated", "patient 1, stimulated")):
        rewards = random_rewards(3, N_STATES, seed=seed)
        demonstrations = {"walk right": RIGHT, "walk up": UP if seed == 0 else UP_LEFT}
        fitted = fitted_job(
            app, client, auth, mdp=mdp, demonstrations=demonstrations, rewards=rewards, demonstrator=name
        )
        out.append(fitted | {"rewards": rewards})
    return out


def compare(
    client: TestClient, auth: dict[str, str], body: dict[str, Any], status: int = 200
) -> dict[str, Any]:
    """POST a comparison, asserting the status."""
    return created(client.post("/v1/comparisons", json=body, headers=auth), status)


def visited(*trajectory_lists: list[dict[str, list[int]]]) -> np.ndarray:
    """Boolean mask of the states in the given trajectories."""
    mask = np.zeros(N_STATES, dtype=bool)
    for trajectories in trajectory_lists:
        for t in trajectories:
            mask[t["states"]] = True
    return mask


def assert_metrics(result: dict[str, Any], x: np.ndarray, y: np.ndarray) -> None:
    """Pearson and Spearman as scipy computes them, EPIC as sqrt((1 − r) / 2), on exactly these states."""
    x, y = x.astype(np.float64), y.astype(np.float64)  # scipy keeps float32 inputs in float32
    r = pearsonr(x, y)[0]
    assert result["pearson"] == pytest.approx(r, abs=1e-9)
    assert result["spearman"] == pytest.approx(spearmanr(x, y)[0], abs=1e-9)
    assert result["epic_distance"] == pytest.approx(np.sqrt((1 - r) / 2), abs=1e-9)
    assert result["n_compared"] == len(x)


def test_two_rewards_match_scipy_on_all_and_visited_states(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    job, rewards = sessions[0], sessions[0]["rewards"]
    task_id, baseline_id = job["reward_ids"][1], job["reward_ids"][0]
    body = {"a": {"reward_id": task_id}, "b": {"reward_id": baseline_id}}
    everywhere = compare(client, auth, body)
    assert_metrics(everywhere, rewards[1], rewards[0])
    assert (everywhere["states"], everywhere["n_states"]) == ("all", N_STATES)
    assert everywhere["a"]["label"] == "walk right — patient 1, unstimulated"
    assert (
        everywhere["b"]["label"] == "baseline — patient 1, unstimulated"
        and everywhere["b"]["task_id"] is None
    )

    # a is the 'walk right' task: its demonstrations; b is the baseline: every task of the job
    on_visited = compare(client, auth, body | {"states": "visited"})
    mask = visited(RIGHT, UP)
    assert_metrics(on_visited, rewards[1][mask], rewards[0][mask])
    assert on_visited["n_compared"] < N_STATES

    task_only = compare(
        client, auth, {"a": {"reward_id": task_id}, "b": {"values": rewards[2].tolist()}, "states": "visited"}
    )
    assert_metrics(task_only, rewards[1][visited(RIGHT)], rewards[2][visited(RIGHT)])
    assert task_only["b"] == {
        "kind": "values",
        "label": "posted values",
        "reward_id": None,
        "job_id": None,
        "task_id": None,
        "demonstrator_id": None,
    }


def test_true_reward_and_posted_values_give_the_same_numbers(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    job = sessions[0]
    truth = (np.arange(N_STATES) % WIDTH).astype(float)
    task_id = job["task_ids"][0]
    a = {"reward_id": job["reward_ids"][1]}
    missing = client.post("/v1/comparisons", json={"a": a, "b": {"task_id": task_id}}, headers=auth)
    assert missing.status_code == 409 and "true-reward" in missing.json()["detail"]

    created(
        client.put(f"/v1/tasks/{task_id}/true-reward", json={"values": truth.tolist()}, headers=auth), 200
    )
    with_truth = compare(client, auth, {"a": a, "b": {"task_id": task_id}})
    with_values = compare(client, auth, {"a": a, "b": {"values": truth.tolist()}})
    assert_metrics(with_truth, job["rewards"][1], truth)
    assert {k: with_truth[k] for k in ("pearson", "spearman", "epic_distance")} == {
        k: with_values[k] for k in ("pearson", "spearman", "epic_distance")
    }
    assert with_truth["b"]["kind"] == "true_reward" and with_truth["b"]["task_id"] == task_id
    listing = client.get(f"/v1/jobs/{job['job_id']}/rewards", headers=auth).json()
    assert listing["tasks"][0]["truth_pearson"] == pytest.approx(with_truth["pearson"], abs=1e-9)


def test_sessions_of_two_demonstrators_compare_by_reward_id(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    off, on = sessions
    for index in (0, 1):  # the baselines, then the 'walk right' rewards
        body = {"a": {"reward_id": off["reward_ids"][index]}, "b": {"reward_id": on["reward_ids"][index]}}
        result = compare(client, auth, body)
        assert_metrics(result, off["rewards"][index], on["rewards"][index])
        assert result["a"]["demonstrator_id"] == off["demonstrator_id"]
        assert result["b"]["demonstrator_id"] == on["demonstrator_id"]
        assert result["b"]["job_id"] == on["job_id"] != result["a"]["job_id"]
        # visited: the states behind a and behind b (baselines: every task of both sessions)
        mask = visited(RIGHT, UP, UP_LEFT) if index == 0 else visited(RIGHT)
        result = compare(client, auth, body | {"states": "visited"})
        assert_metrics(result, off["rewards"][index][mask], on["rewards"][index][mask])


def test_bad_bodies_are_422_naming_the_field(
    app: FastAPI, client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    reward_id = sessions[0]["reward_ids"][1]
    corridor = fitted_job(
        app,
        client,
        auth,
        mdp=created(client.get(f"/v1/mdps/{make_task(client, auth)['mdp_id']}", headers=auth), 200),
        demonstrations={"reach": [{"states": [0, 1, 2], "actions": [1, 1]}]},
        rewards=random_rewards(2, 3),
    )
    small_task = corridor["task_ids"][0]
    created(client.put(f"/v1/tasks/{small_task}/true-reward", json={"values": [0, 0, 1]}, headers=auth), 200)
    a = {"reward_id": reward_id}
    cases: list[tuple[dict[str, Any], str, str]] = [
        ({"a": a, "b": {"values": [1.0, 2.0]}}, "/b/values", "has 2 values; reward a has 20 states"),
        ({"a": a, "b": {"reward_id": corridor["reward_ids"][1]}}, "/b/reward_id", "has 3 values"),
        ({"a": a, "b": {"task_id": small_task}}, "/b/task_id", "has 3 values"),
        ({"a": a, "b": {"values": [0.0, "x"]}}, "/b/values/1", "number"),
        ({"a": a, "b": {"reward_id": reward_id, "values": [1.0]}}, "/b", "exactly one"),
        ({"a": a, "b": {}}, "/b", "exactly one"),
        ({"a": a, "b": {"values": [1.0] * N_STATES}, "states": "some"}, "/states", "'all' or 'visited'"),
        ({"a": {"reward_id": "rwd_nope"}, "b": {"values": [1.0]}}, "/a/reward_id", "no reward with this id"),
        ({"a": a, "b": {"task_id": "task_nope"}}, "/b/task_id", "no task with this id"),
    ]
    for body, pointer, message in cases:
        problem = compare(client, auth, body, 422)
        assert problem["errors"][0]["pointer"] == pointer, (body, problem)
        assert message in problem["errors"][0]["message"], (body, problem)


def pointers(problem: dict[str, Any]) -> list[str]:
    """The pointers of a 422's errors, in order."""
    return [e["pointer"] for e in problem["errors"]]


def test_comparison_with_a_bad_states_value_and_an_unknown_reward_lists_both(
    client: TestClient, auth: dict[str, str]
) -> None:
    body = {"a": {"reward_id": "rwd_nope"}, "b": {"task_id": "task_nope"}, "states": "some"}
    problem = compare(client, auth, body, 422)
    assert pointers(problem) == ["/states", "/a/reward_id", "/b/task_id"]
    assert "'all' or 'visited'" in problem["errors"][0]["message"]
    assert problem["errors"][1]["message"] == "no reward with this id exists in your lab"


def test_comparison_with_bad_weights_and_values_of_the_wrong_length_lists_both(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    body = {
        "a": {"reward_id": sessions[0]["reward_ids"][1]},
        "b": {"values": [1.0, 2.0]},
        "weights": "softmax",
    }
    problem = compare(client, auth, body, 422)
    assert pointers(problem) == ["/weights", "/b/values"]
    assert "has 2 values; reward a has 20 states" in problem["errors"][1]["message"]


def test_a_side_the_schema_refuses_is_not_judged_further_while_the_other_is(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    """b's values hold a string: their length is not compared with a's; a's reward is still looked up."""
    problem = compare(client, auth, {"a": {"reward_id": "rwd_nope"}, "b": {"values": [0.0, "x"]}}, 422)
    assert pointers(problem) == ["/b/values/1", "/a/reward_id"]
    a = {"reward_id": sessions[0]["reward_ids"][1]}
    problem = compare(client, auth, {"a": a, "b": {"task_id": "task_nope", "values": [1.0]}}, 422)
    assert pointers(problem) == ["/b"]


def test_a_task_without_a_true_reward_is_a_409_only_once_nothing_else_is_wrong(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    b = {"task_id": sessions[0]["task_ids"][0]}
    problem = compare(client, auth, {"a": {"reward_id": "rwd_nope"}, "b": b, "states": "some"}, 422)
    assert pointers(problem) == ["/states", "/a/reward_id"]
    conflict = compare(client, auth, {"a": {"reward_id": sessions[0]["reward_ids"][1]}, "b": b}, 409)
    assert "true-reward" in conflict["detail"]


def test_another_labs_rewards_and_tasks_are_unknown(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    theirs = sessions[0]
    body = {"a": {"reward_id": theirs["reward_ids"][1]}, "b": {"values": [0.0] * N_STATES}}
    problem = compare(client, auth_b, body, 422)
    assert problem["errors"] == [
        {"pointer": "/a/reward_id", "message": "no reward with this id exists in your lab"}
    ]
    assert problem == compare(client, auth_b, {"a": {"reward_id": "rwd_nope"}, "b": body["b"]}, 422) | {
        "detail": problem["detail"]
    }
    for path in (
        f"/v1/jobs/{theirs['job_id']}/comparison-matrix",
        f"/v1/rewards/{theirs['reward_ids'][1]}/key-states",
    ):
        assert client.get(path, headers=auth_b).status_code == 404, path


def test_comparison_matrix_is_pairwise_pearson_as_json_and_png(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    job = sessions[0]
    matrix = created(client.get(f"/v1/jobs/{job['job_id']}/comparison-matrix", headers=auth), 200)
    assert matrix["labels"] == ["baseline", "walk right", "walk up"]
    assert matrix["reward_ids"] == job["reward_ids"] and matrix["task_ids"] == [None, *job["task_ids"]]
    np.testing.assert_allclose(matrix["matrix"], np.corrcoef(job["rewards"].astype(np.float64)), atol=1e-12)

    png = client.get(f"/v1/jobs/{job['job_id']}/comparison-matrix", params={"format": "png"}, headers=auth)
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert Image.open(io.BytesIO(png.content)).size == matrix_pixel_size(n=3)
    assert png.content == matrix_png(
        np.asarray(matrix["matrix"]), labels=matrix["labels"], title="Pearson r — patient 1, unstimulated"
    )
    assert (
        png.headers["Content-Disposition"]
        == 'inline; filename="patient-1-unstimulated_all-tasks_pearson.png"'
    )


def test_comparison_matrix_of_an_unfinished_job_is_409(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    client.post(
        f"/v1/tasks/{task['id']}/demonstrations",
        json={"trajectories": [{"states": [0, 1], "actions": [1]}]},
        headers=auth,
    )
    job = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )
    assert client.get(f"/v1/jobs/{job['id']}/comparison-matrix", headers=auth).status_code == 409


def test_key_states_are_the_largest_departures_from_the_baseline(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    job = sessions[0]
    task, baseline = job["rewards"][1].astype(np.float64), job["rewards"][0].astype(np.float64)
    found = created(
        client.get(f"/v1/rewards/{job['reward_ids'][1]}/key-states", params={"top": 4}, headers=auth), 200
    )
    expected = np.argsort(-np.abs(task - baseline))[:4]
    assert [s["state"] for s in found["states"]] == expected.tolist()
    assert (found["baseline_reward_id"], found["task_id"], found["top"]) == (
        job["reward_ids"][0],
        job["task_ids"][0],
        4,
    )
    for rank, item in enumerate(found["states"], start=1):
        s = item["state"]
        assert (item["rank"], item["x"], item["y"], item["channel"]) == (rank, s % WIDTH, s // WIDTH, 0)
        assert item["difference"] == pytest.approx(task[s] - baseline[s])
        assert (item["reward"], item["baseline"]) == (pytest.approx(task[s]), pytest.approx(baseline[s]))

    of_baseline = client.get(f"/v1/rewards/{job['reward_ids'][0]}/key-states", headers=auth)
    assert of_baseline.status_code == 409 and "baseline" in of_baseline.json()["detail"]
    for top in (0, 1001):
        response = client.get(
            f"/v1/rewards/{job['reward_ids'][1]}/key-states", params={"top": top}, headers=auth
        )
        assert response.status_code == 422 and response.json()["errors"][0]["parameter"] == "top"
    default = client.get(f"/v1/rewards/{job['reward_ids'][1]}/key-states", headers=auth).json()
    assert len(default["states"]) == 10


def test_states_where_a_task_reward_equals_the_baseline_are_no_key_states(
    app: FastAPI, client: TestClient, auth: dict[str, str], mdp: dict[str, Any]
) -> None:
    """A task reward that is the baseline lists none and says so; one that departs at 2 states lists those 2."""
    rewards = random_rewards(3, N_STATES, seed=5)
    rewards[1] = rewards[0]
    rewards[2] = rewards[0]
    rewards[2, [3, 7]] += [0.5, -1.0]
    job = fitted_job(
        app, client, auth, mdp=mdp, demonstrations={"walk right": RIGHT, "walk up": UP}, rewards=rewards
    )
    same, two = (
        created(client.get(f"/v1/rewards/{rid}/key-states", params={"top": 5}, headers=auth), 200)
        for rid in job["reward_ids"][1:]
    )
    assert same["states"] == [] and same["note"].startswith(
        "The task reward equals the baseline at every state"
    )
    assert [s["state"] for s in two["states"]] == [7, 3]
    assert two["note"].startswith(f"The task reward differs from the baseline at 2 of {N_STATES} states")
    full = created(
        client.get(f"/v1/rewards/{job['reward_ids'][2]}/key-states", params={"top": 2}, headers=auth), 200
    )
    assert full["note"] is None


def load_example(name: str) -> ModuleType:
    """A script of docs/examples as a module (not run as __main__)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "docs" / "examples" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_compare_sessions_example_pairs_baselines_and_same_named_tasks(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]], tmp_path: Path
) -> None:
    script = load_example("compare_sessions")
    client.headers.update(auth)
    off, on = sessions
    lab = Client(client)  # the lab client around the test app's httpx client
    rows = script.compare_sessions(lab, off["job_id"], on["job_id"])
    assert [row["label"] for row in rows] == ["baseline", "walk right", "walk up"]
    for index, row in enumerate(rows):
        x, y = off["rewards"][index].astype(np.float64), on["rewards"][index].astype(np.float64)
        assert row["pearson"] == pytest.approx(pearsonr(x, y)[0], abs=1e-9)
    paths = script.save_matrices(lab, [off["job_id"], on["job_id"]], tmp_path)
    assert [Image.open(p).size for p in paths] == [matrix_pixel_size(n=3)] * 2


def test_finite_values_near_the_float64_limits_give_finite_correlations(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    huge = [1e308] * (N_STATES // 2) + [-1e308] * (N_STATES - N_STATES // 2)
    out = compare(client, auth, {"a": {"reward_id": sessions[0]["reward_ids"][1]}, "b": {"values": huge}})
    assert out["pearson"] is not None and out["spearman"] is not None
    assert abs(out["pearson"] - pearsonr(sessions[0]["rewards"][1], np.sign(huge)).statistic) < 1e-6


# ---------------------------------------------------------------- distances that know the dynamics


def test_dynamics_epic_and_starc_match_the_engine_and_see_a_permutation(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]], mdp: dict[str, Any]
) -> None:
    from metairl_engine.distances import distances
    from metairl_engine.grids import grid_mdp
    from metairl_engine.planning import transition_matrix

    first = sessions[0]
    x = first["rewards"][1].astype(np.float64)
    reward = {"reward_id": first["reward_ids"][1]}
    same = compare(client, auth, {"a": reward, "b": {"values": (3 * x + 7).tolist()}})["dynamics"]
    assert same["epic"] == pytest.approx(0, abs=1e-6) and same["starc"] == pytest.approx(0, abs=1e-6)
    assert (same["mdp_id"], same["gamma"], same["weights"], same["n_bootstrap"]) == (
        mdp["id"],
        0.9,
        "uniform",
        0,
    )
    assert same["epic_interval"] is None and same["starc_interval"] is None

    permuted = x[np.random.default_rng(0).permutation(x.size)]
    far = compare(client, auth, {"a": reward, "b": {"values": permuted.tolist()}, "bootstrap": 100})[
        "dynamics"
    ]
    engine = grid_mdp(width=WIDTH, height=N_STATES // WIDTH, moves=4, gamma=0.9)
    expected = distances(
        x,
        permuted,
        transitions=transition_matrix(engine),
        gamma=0.9,
        n_actions=engine.n_actions,
        bootstrap=100,
    )
    assert far["epic"] == pytest.approx(expected.epic, abs=1e-6) and far["epic"] > 0.2
    assert far["starc"] == pytest.approx(expected.starc, abs=1e-6) and far["starc"] > 0.2
    assert far["epic_interval"]["low"] <= far["epic"] <= far["epic_interval"]["high"]
    assert far["starc_interval"]["low"] <= far["starc"] <= far["starc_interval"]["high"]
    assert far["n_bootstrap"] == 100
    opposite = compare(client, auth, {"a": reward, "b": {"values": (-x).tolist()}})["dynamics"]
    assert opposite["epic"] == pytest.approx(1.0, abs=1e-6)


def test_occupancy_weights_count_the_demonstrated_states(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    first = sessions[0]
    x = first["rewards"][1].astype(np.float64)
    y = x.copy()
    shown = visited(RIGHT)
    y[~shown] = np.random.default_rng(1).normal(size=int((~shown).sum()))  # differs only where nobody went
    body = {"a": {"reward_id": first["reward_ids"][1]}, "b": {"values": y.tolist()}}
    uniform = compare(client, auth, body)["dynamics"]
    occupancy = compare(client, auth, body | {"weights": "occupancy"})["dynamics"]
    assert occupancy["weights"] == "occupancy" and occupancy["epic"] < uniform["epic"]
    visited_only = compare(client, auth, body | {"weights": "occupancy", "states": "visited"})
    assert visited_only["dynamics"]["epic"] == pytest.approx(occupancy["epic"], abs=1e-9)


@pytest.mark.parametrize(
    ("extra", "pointer"), [({"weights": "softmax"}, "/weights"), ({"bootstrap": 5000}, "/bootstrap")]
)
def test_bad_weighting_or_bootstrap_is_a_422_naming_it(
    client: TestClient,
    auth: dict[str, str],
    sessions: list[dict[str, Any]],
    extra: dict[str, Any],
    pointer: str,
) -> None:
    body = {"a": {"reward_id": sessions[0]["reward_ids"][1]}, "b": {"values": [0.0] * N_STATES}} | extra
    problem = compare(client, auth, body, status=422)
    assert pointer in [e["pointer"] for e in problem["errors"]]


def test_comparison_matrix_has_the_dynamics_epic(
    client: TestClient, auth: dict[str, str], sessions: list[dict[str, Any]]
) -> None:
    matrix = created(client.get(f"/v1/jobs/{sessions[0]['job_id']}/comparison-matrix", headers=auth), 200)
    epic = np.array(matrix["epic"])
    assert epic.shape == (3, 3) and np.allclose(np.diag(epic), 0) and np.allclose(epic, epic.T)
    assert ((epic[~np.eye(3, dtype=bool)] > 0) & (epic[~np.eye(3, dtype=bool)] <= 1)).all()
    baseline_vs_task = compare(
        client,
        auth,
        {"a": {"reward_id": sessions[0]["reward_ids"][0]}, "b": {"reward_id": sessions[0]["reward_ids"][1]}},
    )
    assert epic[0, 1] == pytest.approx(baseline_vs_task["dynamics"]["epic"], abs=1e-9)
