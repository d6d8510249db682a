"""Demonstrations: JSON and CSV uploads, validation against the MDP, appending, all-or-nothing batches."""

from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from service.store.loaders import load_trajectories
from tests.service.helpers import add_demonstrations, created, make_task


def post_csv(client: TestClient, auth: dict[str, str], task_id: str, text: str):
    """Upload `text` as a CSV file."""
    return client.post(
        f"/v1/tasks/{task_id}/demonstrations", files={"file": ("demos.csv", text.encode())}, headers=auth
    )


def test_json_trajectories_are_appended_and_counted(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    first = add_demonstrations(client, auth, task["id"])
    assert first["id"].startswith("trj_") and (
        first["n_trajectories"],
        first["n_steps"],
        first["format"],
    ) == (2, 4, "json")
    add_demonstrations(client, auth, task["id"], [{"states": [1, 2, 2], "actions": [1, 1]}])
    got = client.get(f"/v1/tasks/{task['id']}", headers=auth).json()
    assert (got["n_trajectories"], got["n_steps"]) == (3, 6)
    listed = client.get(f"/v1/tasks/{task['id']}/demonstrations", headers=auth).json()["data"]
    assert [d["n_trajectories"] for d in listed] == [1, 2]
    with app.state.sessionmaker() as session:
        trajectories = load_trajectories(session, task["id"])
    assert [t.states.tolist() for t in trajectories] == [[0, 1, 2], [2, 1], [1, 2, 2]]
    assert [t.actions.tolist() for t in trajectories] == [[1, 1], [0, 0], [1, 1]]


@pytest.mark.parametrize(
    ("trajectories", "pointer", "words"),
    [
        ([{"states": [0, 2], "actions": [1]}], "/trajectories/0/states/1", "cannot lead to state 2"),
        (
            [{"states": [0, 1], "actions": [1]}, {"states": [0, 9], "actions": [1]}],
            "/trajectories/1/states/1",
            "outside 0..2",
        ),
        ([{"states": [0, 1], "actions": [5]}], "/trajectories/0/actions/0", "outside 0..1"),
        ([{"states": [0, 1, 2, 2], "actions": [1]}], "/trajectories/0/states", "4 entries for 1 actions"),
        ([], "/trajectories", "at least one trajectory"),
        ([{"states": [0, 1]}], "/trajectories/0/actions", "Field required"),
    ],
)
def test_invalid_trajectories_are_422_naming_trajectory_and_step(
    client: TestClient, auth: dict[str, str], trajectories: list, pointer: str, words: str
) -> None:
    task = make_task(client, auth)
    response = client.post(
        f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": trajectories}, headers=auth
    )
    assert response.status_code == 422, response.text
    assert any(e["pointer"] == pointer and words in e["message"] for e in response.json()["errors"]), (
        response.json()
    )


def test_a_bad_upload_stores_nothing(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    bad = [{"states": [0, 1, 2], "actions": [1, 1]}, {"states": [0, 2], "actions": [1]}]
    assert (
        client.post(
            f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": bad}, headers=auth
        ).status_code
        == 422
    )
    got = client.get(f"/v1/tasks/{task['id']}", headers=auth).json()
    assert (got["n_trajectories"], got["n_steps"]) == (2, 4)


def test_csv_upload_with_final_state_and_shuffled_rows(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    text = "trajectory,step,state,action\nb,1,1,0\na,0,0,1\na,1,1,1\na,2,2,\nb,0,2,0\n"
    batch = created(post_csv(client, auth, task["id"], text))
    assert (batch["format"], batch["n_trajectories"], batch["n_steps"]) == ("csv", 2, 4)
    with app.state.sessionmaker() as session:
        trajectories = load_trajectories(session, task["id"])
    assert [(t.states.tolist(), t.actions.tolist()) for t in trajectories] == [
        ([2, 1], [0, 0]),
        ([0, 1, 2], [1, 1]),
    ]


@pytest.mark.parametrize(
    ("text", "pointer", "words"),
    [
        (
            "trajectory,step,state,action\na,0,0,1\na,1,0,1\na,2,2,\n",
            "/trajectories/0/states/1",
            "CSV line 3",
        ),
        ("trajectory,step,state,action\na,0,0,1\na,1,x,1\n", "/file", "CSV line 3: state 'x'"),
        ("trajectory,step,state\na,0,0\n", "/file", "missing action"),
        (
            "trajectory,step,state,action\na,0,0,1\na,2,1,\n",
            "/trajectories/0",
            "expected step 1, found 2 (CSV line 3)",
        ),
        (
            "trajectory,step,state,action\na,0,0,\na,1,1,1\na,2,2,\n",
            "/trajectories/0/actions/0",
            "CSV line 2",
        ),
        ("trajectory,step,state,action\n", "/trajectories", "no data rows"),
        ("trajectory,step,state,action\nA,0,0,1\nA,1,1,1,7\nA,2,2,\n", "/file", "CSV line 3: has 5 cells"),
    ],
)
def test_invalid_csv_is_422_with_its_line(
    client: TestClient, auth: dict[str, str], text: str, pointer: str, words: str
) -> None:
    task = make_task(client, auth)
    response = post_csv(client, auth, task["id"], text)
    assert response.status_code == 422, response.text
    assert any(e["pointer"] == pointer and words in e["message"] for e in response.json()["errors"]), (
        response.json()
    )


def test_csv_trailing_empty_cells_are_not_extra_cells(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    response = post_csv(client, auth, task["id"], "trajectory,step,state,action\nA,0,0,1,\nA,1,1,,\n")
    assert response.status_code == 201, response.text
