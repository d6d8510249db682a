"""Demonstrators, their tasks and tasks' true rewards (set, read back, downloaded as files)."""

from __future__ import annotations

import io

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_engine.mdp import Layout
from service.files import exports
from service.store.loaders import load_true_reward
from tests.service.helpers import created, make_demonstrator, make_mdp, make_task


def test_demonstrator_is_created_read_and_listed(client: TestClient, auth: dict[str, str]) -> None:
    dem = make_demonstrator(client, auth, name="patient 7")
    assert dem["id"].startswith("dem_") and dem["metadata"] == {"age": 40}
    assert client.get(f"/v1/demonstrators/{dem['id']}", headers=auth).json() == dem
    listed = client.get("/v1/demonstrators", headers=auth).json()
    assert listed == {"data": [dem], "has_more": False, "next_cursor": None}


def test_task_is_created_in_a_demonstrator_and_listed(client: TestClient, auth: dict[str, str]) -> None:
    dem = make_demonstrator(client, auth)
    mdp = make_mdp(client, auth)
    response = client.post(
        f"/v1/demonstrators/{dem['id']}/tasks",
        json={"name": "reach", "mdp_id": mdp["id"], "metadata": {"k": 1}},
        headers=auth,
    )
    task = created(response)
    assert task["id"].startswith("task_") and response.headers["location"] == f"/v1/tasks/{task['id']}"
    assert (task["demonstrator_id"], task["mdp_id"], task["metadata"]) == (dem["id"], mdp["id"], {"k": 1})
    assert (task["n_trajectories"], task["n_steps"], task["has_true_reward"]) == (0, 0, False)
    assert client.get(f"/v1/tasks/{task['id']}", headers=auth).json() == task
    assert client.get(f"/v1/demonstrators/{dem['id']}/tasks", headers=auth).json()["data"] == [task]


def test_task_with_another_labs_mdp_is_422_at_mdp_id(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    foreign = make_mdp(client, auth_b)
    for mdp_id in (foreign["id"], "mdp_missing"):
        response = client.post(
            f"/v1/demonstrators/{dem['id']}/tasks", json={"name": "t", "mdp_id": mdp_id}, headers=auth
        )
        assert response.status_code == 422
        assert response.json()["errors"] == [{"pointer": "/mdp_id", "message": f"no MDP with id {mdp_id!r}"}]


def test_true_reward_is_stored_replaced_and_read(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    url = f"/v1/tasks/{task['id']}/true-reward"
    assert client.get(url, headers=auth).status_code == 404
    first = client.put(url, json={"values": [0, 0, 1]}, headers=auth)
    assert first.status_code == 200 and first.json()["n_states"] == 3
    client.put(url, json={"values": [1, 0.5, 0]}, headers=auth)
    assert client.get(url, headers=auth).json()["values"] == [1.0, 0.5, 0.0]
    assert client.get(f"/v1/tasks/{task['id']}", headers=auth).json()["has_true_reward"] is True
    with app.state.sessionmaker() as session:
        stored = load_true_reward(session, task["id"])
    assert stored is not None and stored.tolist() == [1.0, 0.5, 0.0]


@pytest.mark.parametrize(
    ("values", "pointer", "words"),
    [
        ([0, 1], "/values", "has 2 values but the MDP has 3 states"),
        ([0, "x", 1], "/values/1", "valid number"),
    ],
)
def test_invalid_true_reward_is_422(
    client: TestClient, auth: dict[str, str], values: list, pointer: str, words: str
) -> None:
    task = make_task(client, auth)
    response = client.put(f"/v1/tasks/{task['id']}/true-reward", json={"values": values}, headers=auth)
    assert response.status_code == 422
    assert any(e["pointer"] == pointer and words in e["message"] for e in response.json()["errors"]), (
        response.json()
    )


def test_non_finite_true_reward_is_422(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    response = client.put(
        f"/v1/tasks/{task['id']}/true-reward",
        content=b'{"values": [0, NaN, 1]}',
        headers=auth | {"Content-Type": "application/json"},
    )
    assert response.status_code == 422
    assert response.json()["errors"][0]["pointer"] == "/values/1"


def test_put_answers_what_get_reads_with_the_values_as_stored(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    url = f"/v1/tasks/{task['id']}/true-reward"
    put = client.put(url, json={"values": [0.1, -2, 1e-3]}, headers=auth)
    assert put.status_code == 200, put.text
    assert (
        put.json()
        == client.get(url, headers=auth).json()
        == client.get(url, params={"format": "json"}, headers=auth).json()
    )
    assert (
        put.json()["values"] == np.array([0.1, -2, 1e-3], dtype=np.float32).tolist()
    )  # float32, as stored and scored


def test_true_reward_downloads_as_npy_and_csv_as_a_learned_reward_does(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)  # the corridor: 3 states on a 3×1 layout
    url = f"/v1/tasks/{task['id']}/true-reward"
    created(client.put(url, json={"values": [0.5, 0, 1]}, headers=auth), 200)

    npy = client.get(url, params={"format": "npy"}, headers=auth)
    assert npy.status_code == 200 and npy.headers["content-type"] == "application/octet-stream"
    values = np.load(io.BytesIO(npy.content), allow_pickle=False)
    assert values.dtype == np.float32 and values.tolist() == [0.5, 0.0, 1.0]
    assert npy.headers["content-disposition"] == 'attachment; filename="patient-1_reach_true-reward.npy"'

    csv = client.get(url, params={"format": "csv"}, headers=auth)
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")
    assert csv.text == "state,x,y,channel,true_reward\n0,0,0,0,0.5\n1,1,0,0,0\n2,2,0,0,1\n"
    assert csv.headers["content-disposition"] == 'attachment; filename="patient-1_reach_true-reward.csv"'
    assert csv.text == exports.to_csv(
        values, layout=Layout(3, 1), quantity="true_reward"
    )  # one writer for both

    unchanged = client.get(
        url, params={"format": "csv"}, headers=auth | {"If-None-Match": csv.headers["ETag"]}
    )
    assert unchanged.status_code == 304 and unchanged.content == b""
    created(client.put(url, json={"values": [1, 0, 0.5]}, headers=auth), 200)
    replaced = client.get(
        url, params={"format": "csv"}, headers=auth | {"If-None-Match": csv.headers["ETag"]}
    )
    assert replaced.status_code == 200 and replaced.text.endswith("2,2,0,0,0.5\n")


@pytest.mark.parametrize("fmt", ["png", "xml", ""])
def test_an_unknown_true_reward_format_is_422_naming_format(
    client: TestClient, auth: dict[str, str], fmt: str
) -> None:
    task = make_task(client, auth)
    url = f"/v1/tasks/{task['id']}/true-reward"
    created(client.put(url, json={"values": [0, 0, 1]}, headers=auth), 200)
    response = client.get(url, params={"format": fmt}, headers=auth)
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    assert [e["parameter"] for e in response.json()["errors"]] == ["format"]


def test_a_task_without_a_true_reward_is_404_in_every_format(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    for fmt in ("json", "npy", "csv"):
        response = client.get(f"/v1/tasks/{task['id']}/true-reward", params={"format": fmt}, headers=auth)
        assert response.status_code == 404 and "no true reward" in response.json()["detail"]
