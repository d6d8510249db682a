"""Bad input of any shape is a 4xx problem, never a 500."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.service.helpers import make_task


def npz(**arrays: object) -> bytes:
    """An .npz archive of `arrays`."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


ODD_MDPS = [
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": [[10**30]]},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": [[0], [0, 1]]},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": []},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "sparse", "s": [], "a": [], "next": [], "p": []},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "n_states": -1,
        "transitions": {"kind": "sparse", "s": [0], "a": [0], "next": [0], "p": [1]},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "sparse", "s": [0], "a": [0], "next": [0, 1], "p": [1]},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "features": [[1e308, -1e308]],
        "transitions": {"kind": "deterministic", "next_state": [[0]]},
    },
    {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": [[0]]},
        "layout": {"width": 0, "height": 1},
    },
    {"kind": "grid", "name": "g", "width": 100_000, "height": 100_000, "gamma": 0.9},
    {"kind": "grid", "name": "g", "width": 3, "height": 3, "moves": 4, "velocity": True, "gamma": 0.9},
    {"kind": "grid", "name": "g", "width": 3, "height": 3, "gamma": -0.1},
    [1, 2, 3],
    "just a string",
    {"kind": None},
]


@pytest.mark.parametrize("body", ODD_MDPS)
def test_odd_mdp_bodies_are_422(client: TestClient, auth: dict[str, str], body: object) -> None:
    response = client.post("/v1/mdps", json=body, headers=auth)
    assert response.status_code == 422, response.text
    assert response.json()["errors"]


@pytest.mark.parametrize(
    ("body", "pointer", "words"),
    [
        ({"kind": "hex", "name": "m"}, "/kind", "'explicit', 'grid'"),
        ({"name": "m"}, "/kind", "is required"),
        (
            '{"kind": "grid", "name": "g", "width": 3, "height": 3, "gamma": 0.9, "slip": NaN}',
            "/slip",
            "finite",
        ),
        ({"kind": "grid", "name": "g", "width": 10**30, "height": 3, "gamma": 0.9}, "/width", "METAIRL_"),
    ],
)
def test_an_odd_mdp_body_is_422_at_the_field_that_makes_it_odd(
    client: TestClient, auth: dict[str, str], body: object, pointer: str, words: str
) -> None:
    if isinstance(body, str):  # NaN as JavaScript writes it, which Python's json reads
        response = client.post("/v1/mdps", content=body, headers=auth | {"Content-Type": "application/json"})
    else:
        response = client.post("/v1/mdps", json=body, headers=auth)
    assert response.status_code == 422, response.text
    (error,) = response.json()["errors"]
    assert error["pointer"] == pointer and words in error["message"], error


@pytest.mark.parametrize(
    ("arrays", "data"),
    [
        ({"next_state": np.array([["a", "b"]])}, {"name": "m", "gamma": "0.9"}),
        ({"next_state": np.zeros((2, 2, 2), dtype=np.int32)}, {"name": "m", "gamma": "0.9"}),
        ({"next_state": np.zeros((1, 1), dtype=np.int32)}, {"name": "m", "gamma": "nan"}),
        ({"next_state": np.zeros((1, 1), dtype=np.int32)}, {"name": "m", "gamma": "0.9", "width": "1"}),
        (
            {"next_state": np.zeros((1, 1), dtype=np.int32)},
            {"name": "m", "gamma": "0.9", "width": "1", "height": "1", "channels": "0"},
        ),
        (
            {"features": np.full((1, 1), np.inf), "next_state": np.zeros((1, 1), dtype=np.int32)},
            {"name": "m", "gamma": "0.9"},
        ),
        ({}, {"name": "m", "gamma": "0.9"}),
    ],
)
def test_odd_npz_uploads_are_422(client: TestClient, auth: dict[str, str], arrays: dict, data: dict) -> None:
    response = client.post("/v1/mdps", files={"file": ("mdp.npz", npz(**arrays))}, data=data, headers=auth)
    assert response.status_code == 422, response.text


@pytest.mark.parametrize(
    "body",
    [
        {"trajectories": [{"states": [10**30], "actions": [0]}]},
        {"trajectories": [{"states": [[0]], "actions": [0]}]},
        {"trajectories": "none"},
        {"trajectories": [{"states": [0, 1], "actions": []}]},
    ],
)
def test_odd_demonstrations_are_422(client: TestClient, auth: dict[str, str], body: object) -> None:
    task = make_task(client, auth)
    response = client.post(f"/v1/tasks/{task['id']}/demonstrations", json=body, headers=auth)
    assert response.status_code == 422, response.text


@pytest.mark.parametrize(
    "payload", [b"\xff\xfe\x00garbage", b"trajectory,step,state,action\na,0,99999999999999,1\n"]
)
def test_odd_csv_files_are_422(client: TestClient, auth: dict[str, str], payload: bytes) -> None:
    task = make_task(client, auth)
    response = client.post(
        f"/v1/tasks/{task['id']}/demonstrations", files={"file": ("d.csv", payload)}, headers=auth
    )
    assert response.status_code == 422, response.text


@pytest.mark.parametrize(
    ("metadata", "words"),
    [({"notes": "x" * 70_000}, "at most 65,536"), ({"weight": float("nan")}, "finite")],
)
def test_metadata_too_large_or_not_finite_is_422_at_metadata_and_stores_nothing(
    client: TestClient, auth: dict[str, str], metadata: dict, words: str
) -> None:
    body = json.dumps({"name": "p", "metadata": metadata})  # NaN as JavaScript writes it
    response = client.post(
        "/v1/demonstrators", content=body, headers=auth | {"Content-Type": "application/json"}
    )
    assert response.status_code == 422, response.text
    (error,) = response.json()["errors"]
    assert error["pointer"] == "/metadata" and words in error["message"], error
    assert client.get("/v1/demonstrators", headers=auth).json()["data"] == []
    ok = {"notes": "x" * 60_000}
    assert (
        client.post("/v1/demonstrators", json={"name": "p", "metadata": ok}, headers=auth).status_code == 201
    )


def test_a_misspelt_field_is_422_at_it_rather_than_left_at_its_default(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    body = {"demonstrator_id": task["demonstrator_id"], "task_id": [task["id"]]}  # for task_ids
    response = client.post("/v1/jobs", json=body, headers=auth)
    assert response.status_code == 422, response.text
    (error,) = response.json()["errors"]
    assert error["pointer"] == "/task_id" and "misspelt" in error["message"]
    grid = {"kind": "grid", "name": "g", "width": 3, "height": 3, "gamma": 0.9, "velocty": True}
    assert client.post("/v1/mdps", json=grid, headers=auth).json()["errors"][0]["pointer"] == "/velocty"
    assert client.get("/v1/jobs", headers=auth).json()["data"] == []
