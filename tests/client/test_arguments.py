"""What the client does with arguments before sending them: one task id where a list is expected is that
one task, a NaN a JSON body cannot carry is a `MetairlError` raised before anything is sent, and a CSV given
by its path is read from there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from metairl_client import Client, InvalidRequestError, MetairlError
from tests.service.helpers import add_demonstrations, make_task


def test_one_task_id_given_as_a_string_submits_that_task(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    client.headers.update(auth)
    job = Client(client).submit_job(task["demonstrator_id"], task_ids=task["id"])
    assert client.get(f"/v1/jobs/{job.id}").json()["task_ids"] == [task["id"]]


def test_a_nan_in_a_json_body_is_a_metairl_error_and_nothing_is_sent(client: TestClient) -> None:
    sent: list[str] = []
    client.event_hooks["request"].append(lambda request: sent.append(str(request.url)))
    with pytest.raises(InvalidRequestError) as refused:
        Client(client).compare("rwd_x", np.array([np.nan, 1.0]))
    assert isinstance(refused.value, MetairlError) and "nothing was sent" in str(refused.value)
    assert refused.value.request == "POST /v1/comparisons" and sent == []


def test_trajectories_as_the_apis_json_or_as_whole_floats_are_sent_as_integer_trajectories(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    client.headers.update(auth)
    loaded = np.loadtxt(["0 1 2"])  # float64, as a lab's text file gives them
    Client(client).add_demonstrations(
        task["id"], [{"states": [0, 1, 2], "actions": [1, 1]}, (loaded, np.array([1.0, 1.0]))]
    )
    listed = client.get(f"/v1/tasks/{task['id']}").json()
    assert (listed["n_trajectories"], listed["n_steps"]) == (2, 4)


def test_a_trajectory_of_another_shape_is_an_invalid_request_naming_it_and_nothing_is_sent(
    client: TestClient,
) -> None:
    sent: list[str] = []
    client.event_hooks["request"].append(lambda request: sent.append(str(request.url)))
    with pytest.raises(InvalidRequestError) as refused:
        Client(client).add_demonstrations("task_x", [([0, 1], [1]), [0, 1, 2]])  # type: ignore[list-item]
    assert "trajectory 1 is a list" in str(refused.value) and sent == []


def test_numpy_arrays_in_a_json_body_are_sent_as_the_lists_they_hold(
    client: TestClient, auth: dict[str, str]
) -> None:
    client.headers.update(auth)
    mdp_id = Client(client).create_mdp(
        {
            "kind": "explicit",
            "name": "corridor from numpy",
            "n_states": np.int64(3),
            "n_actions": 2,
            "gamma": np.float32(0.5),
            "transitions": {"kind": "deterministic", "next_state": np.array([[0, 1], [0, 2], [1, 2]])},
        }
    )
    mdp = client.get(f"/v1/mdps/{mdp_id}").json()
    assert (mdp["n_states"], mdp["gamma"]) == (3, 0.5)


def test_a_demonstrations_csv_given_by_a_path_string_is_read_from_that_file(
    client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    task = make_task(client, auth)
    client.headers.update(auth)
    path = tmp_path / "walks.csv"
    path.write_text("trajectory,step,state,action\nw,0,0,1\nw,1,1,1\nw,2,2,\n")
    lab = Client(client)
    batch_id = lab.upload_demonstrations(task["id"], str(path))
    assert lab.get_demonstrations(task["id"], batch_id)["trajectories"] == [
        {"states": [0, 1, 2], "actions": [1, 1]}
    ]
