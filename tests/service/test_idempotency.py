"""`Idempotency-Key`: a retried POST replays the first response and creates nothing; a changed body is a 422."""

from __future__ import annotations

import secrets

from fastapi.testclient import TestClient

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings
from tests.service.helpers import CORRIDOR_NEXT_STATE, make_task


def count_demonstrators(client: TestClient, auth: dict[str, str]) -> int:
    """How many demonstrators the lab has."""
    return len(client.get("/v1/demonstrators", headers=auth, params={"limit": 100}).json()["data"])


def test_same_key_and_body_replays_the_first_response(client: TestClient, auth: dict[str, str]) -> None:
    headers = auth | {"Idempotency-Key": "create-p1"}
    first = client.post("/v1/demonstrators", json={"name": "p1", "metadata": {"a": 1}}, headers=headers)
    again = client.post("/v1/demonstrators", json={"metadata": {"a": 1}, "name": "p1"}, headers=headers)
    assert first.status_code == again.status_code == 201
    assert again.json() == first.json()
    assert again.headers["location"] == first.headers["location"]
    assert again.headers["idempotent-replayed"] == "true"
    assert count_demonstrators(client, auth) == 1


def test_same_key_with_a_different_body_is_422(client: TestClient, auth: dict[str, str]) -> None:
    headers = auth | {"Idempotency-Key": "k"}
    assert client.post("/v1/demonstrators", json={"name": "p1"}, headers=headers).status_code == 201
    response = client.post("/v1/demonstrators", json={"name": "p2"}, headers=headers)
    assert response.status_code == 422
    assert response.json()["errors"][0]["parameter"] == "Idempotency-Key"
    assert count_demonstrators(client, auth) == 1


def test_keys_are_scoped_per_lab(client: TestClient, auth: dict[str, str], auth_b: dict[str, str]) -> None:
    a = client.post("/v1/demonstrators", json={"name": "p"}, headers=auth | {"Idempotency-Key": "shared"})
    b = client.post("/v1/demonstrators", json={"name": "p"}, headers=auth_b | {"Idempotency-Key": "shared"})
    assert a.status_code == b.status_code == 201
    assert a.json()["id"] != b.json()["id"]
    assert "idempotent-replayed" not in b.headers


def test_multipart_uploads_replay_despite_new_boundaries(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    csv = b"trajectory,step,state,action\na,0,0,1\na,1,1,1\na,2,2,\n"
    url = f"/v1/tasks/{task['id']}/demonstrations"
    headers = auth | {"Idempotency-Key": "upload-1"}
    first = client.post(url, files={"file": ("d.csv", csv)}, headers=headers)
    again = client.post(url, files={"file": ("d.csv", csv)}, headers=headers)
    assert first.status_code == again.status_code == 201
    assert again.json()["id"] == first.json()["id"]
    assert client.get(f"/v1/tasks/{task['id']}", headers=auth).json()["n_trajectories"] == 1


def test_validation_failures_are_replayed_too(client: TestClient, auth: dict[str, str]) -> None:
    body = {
        "kind": "explicit",
        "name": "m",
        "gamma": 2.0,
        "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
    }
    headers = auth | {"Idempotency-Key": "bad-mdp"}
    first = client.post("/v1/mdps", json=body, headers=headers)
    again = client.post("/v1/mdps", json=body, headers=headers)
    assert first.status_code == again.status_code == 422
    assert again.json() == first.json()


def test_requests_without_a_valid_key_are_not_remembered(client: TestClient, auth: dict[str, str]) -> None:
    bad = {"Authorization": "Bearer nope", "Idempotency-Key": "x"}
    assert client.post("/v1/demonstrators", json={"name": "p"}, headers=bad).status_code == 401
    response = client.post("/v1/demonstrators", json={"name": "p"}, headers=auth | {"Idempotency-Key": "x"})
    assert response.status_code == 201 and "idempotent-replayed" not in response.headers


def test_a_key_expires_after_the_ttl(settings: Settings) -> None:
    app = create_app(settings.model_copy(update={"idempotency_ttl_s": 0}))
    with app.state.sessionmaker() as session:
        headers = {
            "Authorization": f"Bearer {create_key(session, f'ttl-{secrets.token_hex(4)}')}",
            "Idempotency-Key": "k",
        }
    with TestClient(app) as client:
        first = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
        again = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    app.state.engine.dispose()
    assert first.status_code == again.status_code == 201
    assert first.json()["id"] != again.json()["id"]
