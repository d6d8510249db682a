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


def test_a_batch_reads_back_with_its_metadata_and_trajectories_as_uploaded(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    uploaded = [{"states": [0, 1, 2], "actions": [1, 1]}, {"states": [2, 1], "actions": [0, 0]}]
    batch = add_demonstrations(client, auth, task["id"], uploaded)
    response = client.get(f"/v1/tasks/{task['id']}/demonstrations/{batch['id']}", headers=auth)
    assert response.status_code == 200, response.text
    body = response.json()
    assert (
        body.pop("trajectories") == uploaded
    )  # the one without a final state keeps as many states as actions
    assert body == batch


def test_a_batch_as_csv_is_what_the_upload_route_takes_back(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    text = "trajectory,step,state,action\nb,1,1,0\na,0,0,1\na,1,1,1\na,2,2,\nb,0,2,0\n"
    batch = created(post_csv(client, auth, task["id"], text))
    url = f"/v1/tasks/{task['id']}/demonstrations/{batch['id']}"
    response = client.get(url, params={"format": "csv"}, headers=auth)
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    assert (
        response.headers["content-disposition"]
        == f'attachment; filename="patient-1_reach_demonstrations_{batch["id"]}.csv"'
    )
    # Trajectories numbered in upload order (b came first), the final state's action empty.
    assert response.text == "trajectory,step,state,action\n0,0,2,0\n0,1,1,0\n1,0,0,1\n1,1,1,1\n1,2,2,\n"

    again = created(post_csv(client, auth, task["id"], response.text))
    copy = client.get(f"/v1/tasks/{task['id']}/demonstrations/{again['id']}", headers=auth).json()
    assert copy["trajectories"] == client.get(url, headers=auth).json()["trajectories"]
    assert (copy["n_trajectories"], copy["n_steps"]) == (batch["n_trajectories"], batch["n_steps"])


@pytest.mark.parametrize("fmt", ["xml", "npy", ""])
def test_an_unknown_batch_format_is_422_naming_format(
    client: TestClient, auth: dict[str, str], fmt: str
) -> None:
    task = make_task(client, auth)
    batch = add_demonstrations(client, auth, task["id"])
    response = client.get(
        f"/v1/tasks/{task['id']}/demonstrations/{batch['id']}", params={"format": fmt}, headers=auth
    )
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    assert [e["parameter"] for e in response.json()["errors"]] == ["format"]


def test_a_batch_is_found_only_under_its_own_task_and_lab(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    task = make_task(client, auth)
    other = make_task(client, auth, demonstrator_id=task["demonstrator_id"], mdp_id=task["mdp_id"])
    batch = add_demonstrations(client, auth, task["id"])
    for task_id, batch_id, headers in (
        (task["id"], "trj_missing", auth),  # no such batch
        (other["id"], batch["id"], auth),  # a batch of another task of the lab
        (task["id"], batch["id"], auth_b),  # another lab: as if it did not exist
    ):
        url = f"/v1/tasks/{task_id}/demonstrations/{batch_id}"
        for method in ("GET", "DELETE"):
            response = client.request(method, url, headers=headers)
            assert response.status_code == 404, (method, url, response.text)
            assert response.headers["content-type"].startswith("application/problem+json")
            named = batch_id if headers is auth else task_id  # lab B does not even see the task
            assert repr(named) in response.json()["detail"], response.json()
    assert client.get(f"/v1/tasks/{task['id']}/demonstrations/{batch['id']}", headers=auth).status_code == 200
