"""`/v1/mdps`: explicit, sparse, grid and `.npz` MDPs, their validation errors, metadata and arrays."""

from __future__ import annotations

import io
import time
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import event

from tests.service.helpers import CORRIDOR_NEXT_STATE, created, make_mdp

SPARSE = {"kind": "sparse", "s": [0, 0, 1], "a": [0, 0, 0], "next": [0, 1, 1], "p": [0.2, 0.8, 1.0]}


def npz_bytes(**arrays: np.ndarray) -> bytes:
    """An .npz archive of `arrays`."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def problem(response, status: int = 422) -> dict:
    """The problem document of an error response, checked for its media type and status."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    body: dict = response.json()
    assert body["status"] == status
    return body


def test_explicit_deterministic_mdp_is_created_with_summary(client: TestClient, auth: dict[str, str]) -> None:
    response = client.post(
        "/v1/mdps",
        json={
            "kind": "explicit",
            "name": "corridor",
            "gamma": 0.9,
            "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
        },
        headers=auth,
    )
    mdp = created(response)
    assert mdp["id"].startswith("mdp_")
    assert response.headers["location"] == f"/v1/mdps/{mdp['id']}"
    assert (mdp["n_states"], mdp["n_actions"], mdp["tabular"], mdp["transitions"]) == (
        3,
        2,
        True,
        "deterministic",
    )
    assert mdp["summary"]["n_transitions"] == 6
    assert client.get(f"/v1/mdps/{mdp['id']}", headers=auth).json() == mdp


def test_sparse_mdp_with_features(client: TestClient, auth: dict[str, str]) -> None:
    mdp = make_mdp(
        client, auth, n_states=2, n_actions=1, transitions=SPARSE, features=[[0, 1], [1, 0]], layout=None
    )
    assert (mdp["transitions"], mdp["n_features"], mdp["tabular"]) == ("sparse", 2, False)
    assert mdp["arrays"]["p"]["shape"] == [3]


def test_grid_mdp_is_built_server_side_with_layout(client: TestClient, auth: dict[str, str]) -> None:
    body = {"kind": "grid", "name": "plate", "width": 5, "height": 4, "velocity": True, "gamma": 0.9}
    mdp = created(client.post("/v1/mdps", json=body, headers=auth))
    assert (mdp["n_states"], mdp["n_actions"]) == (5 * 4 * 8, 8)
    assert mdp["layout"] == {"width": 5, "height": 4, "channels": 8}
    assert mdp["grid"]["moves"] == 8 and mdp["source"] == "grid"


@pytest.mark.parametrize(
    ("change", "pointer", "words"),
    [
        ({"gamma": 1.5}, "/gamma", "[0, 1)"),
        (
            {"transitions": {"kind": "deterministic", "next_state": [[0, 1], [0, 7], [1, 2]]}},
            "/transitions/next_state/1/1",
            "outside 0..2",
        ),
        (
            {"transitions": {"kind": "deterministic", "next_state": [[0, 1.5], [0, 2], [1, 2]]}},
            "/transitions/next_state/0/1",
            "integer",
        ),
        (
            {"transitions": SPARSE | {"p": [0.2, 0.7, 1.0]}, "n_states": 2, "n_actions": 1, "layout": None},
            "/transitions/p",
            "sum to",
        ),
        ({"layout": {"width": 2, "height": 2}}, "/layout", "3 states"),
        ({"features": [[1.0], [2.0]]}, "/features", "rows"),
        ({"name": ""}, "/name", "at least 1"),
        ({"kind": "hexagonal"}, "/kind", "hexagonal"),
    ],
)
def test_invalid_explicit_mdps_are_422_with_pointer(
    client: TestClient, auth: dict[str, str], change: dict, pointer: str, words: str
) -> None:
    body = {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
    } | change
    errors = problem(client.post("/v1/mdps", json=body, headers=auth))["errors"]
    assert any(e["pointer"] == pointer and words in e["message"] for e in errors), errors


def test_missing_field_points_at_it(client: TestClient, auth: dict[str, str]) -> None:
    body = {"kind": "grid", "name": "g", "width": 3, "gamma": 0.9}
    errors = problem(client.post("/v1/mdps", json=body, headers=auth))["errors"]
    assert errors == [{"pointer": "/height", "message": "Field required"}]


def test_an_explicit_mdp_with_a_bad_gamma_and_a_next_state_out_of_range_lists_both(
    client: TestClient, auth: dict[str, str]
) -> None:
    body = {
        "kind": "explicit",
        "name": "m",
        "gamma": "0.9",  # a string: refused by the schema
        "transitions": {"kind": "deterministic", "next_state": [[0, 1], [0, 7], [1, 2]]},
    }
    errors = problem(client.post("/v1/mdps", json=body, headers=auth))["errors"]
    assert [e["pointer"] for e in errors] == ["/gamma", "/transitions/next_state/1/1"]
    assert "outside 0..2" in errors[1]["message"]
    assert client.get("/v1/mdps", headers=auth).json()["data"] == []


def test_features_of_the_wrong_row_count_come_with_the_schemas_problems_elsewhere(
    client: TestClient, auth: dict[str, str]
) -> None:
    """The layout the schema refuses is not checked against the states; the features still are."""
    body = {
        "kind": "explicit",
        "name": "",
        "gamma": 0.9,
        "features": [[1.0], [2.0]],
        "layout": {"width": "3", "height": 1},
        "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
    }
    errors = problem(client.post("/v1/mdps", json=body, headers=auth))["errors"]
    assert [e["pointer"] for e in errors] == ["/name", "/layout/width", "/features"]
    assert "has 2 rows but the MDP has 3 states" in errors[2]["message"]


def test_the_engine_judges_the_arrays_without_refused_features_but_not_without_valid_counts(
    client: TestClient, auth: dict[str, str]
) -> None:
    corridor: dict[str, Any] = {
        "kind": "explicit",
        "name": "m",
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
    }
    cases: list[tuple[dict[str, Any], list[str]]] = [
        (
            {"features": [[1.0], ["x"], [2.0]], "layout": {"width": 2, "height": 2}},
            ["/features/1/0", "/layout"],
        ),
        ({"n_states": "3", "features": [[1.0], [2.0]]}, ["/n_states"]),  # the count the arrays are judged by
        (
            {"transitions": {"kind": "deterministic", "next_state": [[0, "x"]]}, "n_actions": 0},
            ["/transitions/next_state/0/1"],
        ),
    ]
    for change, expected in cases:
        errors = problem(client.post("/v1/mdps", json=corridor | change, headers=auth))["errors"]
        assert [e["pointer"] for e in errors] == expected, (change, errors)


def test_a_grid_with_a_bad_gamma_and_over_the_size_limit_lists_both(
    client: TestClient, auth: dict[str, str]
) -> None:
    body = {"kind": "grid", "name": "g", "width": 100_000, "height": 100_000, "gamma": "high"}
    errors = problem(client.post("/v1/mdps", json=body, headers=auth))["errors"]
    assert [e["pointer"] for e in errors] == ["/gamma", "/width"]
    assert "METAIRL_MAX_STATE_ACTIONS" in errors[1]["message"]


def test_malformed_json_and_wrong_media_type(client: TestClient, auth: dict[str, str]) -> None:
    bad_json = client.post(
        "/v1/mdps", content=b"{not json", headers=auth | {"Content-Type": "application/json"}
    )
    assert "JSON" in problem(bad_json)["errors"][0]["message"]
    assert problem(client.post("/v1/mdps", content=b"x", headers=auth | {"Content-Type": "text/plain"}), 415)


def test_npz_upload_round_trips_through_arrays_download(client: TestClient, auth: dict[str, str]) -> None:
    features = np.random.default_rng(0).random((3, 4)).astype(np.float32)
    next_state = np.array(CORRIDOR_NEXT_STATE, dtype=np.int32)
    response = client.post(
        "/v1/mdps",
        files={"file": ("mdp.npz", npz_bytes(features=features, next_state=next_state))},
        data={"name": "uploaded", "gamma": "0.95", "width": "3", "height": "1"},
        headers=auth,
    )
    mdp = created(response)
    assert (mdp["source"], mdp["n_features"], mdp["layout"]["width"]) == ("npz", 4, 3)
    download = client.get(f"/v1/mdps/{mdp['id']}/arrays", headers=auth)
    assert download.status_code == 200
    with np.load(io.BytesIO(download.content), allow_pickle=False) as archive:
        np.testing.assert_array_equal(archive["features"], features)
        np.testing.assert_array_equal(archive["next_state"], next_state)


@pytest.mark.parametrize(
    ("file", "data", "pointer"),
    [
        (b"not a zip", {"name": "x", "gamma": "0.9"}, "/file"),
        (
            npz_bytes(next_state=np.array(CORRIDOR_NEXT_STATE), extra=np.zeros(2)),
            {"name": "x", "gamma": "0.9"},
            "/file",
        ),
        (npz_bytes(next_state=np.array(CORRIDOR_NEXT_STATE)), {"name": "x"}, "/gamma"),
        (npz_bytes(next_state=np.array(CORRIDOR_NEXT_STATE)), {"name": "x", "gamma": "high"}, "/gamma"),
        (npz_bytes(next_state=np.array(CORRIDOR_NEXT_STATE)), {"gamma": "0.9"}, "/name"),
        (
            npz_bytes(next_state=np.array([[0, 5], [0, 2], [1, 2]])),
            {"name": "x", "gamma": "0.9"},
            "/transitions/next_state/0/1",
        ),
    ],
)
def test_invalid_npz_uploads_are_422_with_pointer(
    client: TestClient, auth: dict[str, str], file: bytes, data: dict, pointer: str
) -> None:
    response = client.post("/v1/mdps", files={"file": ("mdp.npz", file)}, data=data, headers=auth)
    assert [e["pointer"] for e in problem(response)["errors"]] == [pointer]


def test_reading_metadata_never_loads_array_payloads(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = make_mdp(client, auth)
    statements: list[str] = []

    def record(conn, cursor, statement, parameters, context, executemany) -> None:
        statements.append(statement)

    event.listen(app.state.engine, "before_cursor_execute", record)
    try:
        assert client.get(f"/v1/mdps/{mdp['id']}", headers=auth).status_code == 200
        assert client.get("/v1/mdps", headers=auth).status_code == 200
    finally:
        event.remove(app.state.engine, "before_cursor_execute", record)
    assert statements and not any("blobs.data" in s for s in statements), statements


def test_an_80000_state_8_action_npz_uploads_in_seconds(client: TestClient, auth: dict[str, str]) -> None:
    rng = np.random.default_rng(1)
    n_states = 80_000
    arrays = {
        "features": rng.random((n_states, 10)).astype(np.float32),
        "next_state": rng.integers(0, n_states, (n_states, 8)).astype(np.int32),
    }
    payload = npz_bytes(**arrays)
    start = time.perf_counter()
    response = client.post(
        "/v1/mdps", files={"file": ("mdp.npz", payload)}, data={"name": "big", "gamma": "0.9"}, headers=auth
    )
    elapsed = time.perf_counter() - start
    assert created(response)["n_states"] == n_states
    assert elapsed < 5.0, f"upload took {elapsed:.2f} s"
