"""`Idempotency-Key`: a retried POST replays the first response and creates nothing; a changed body is a 422;
a claim whose request never recorded its response lapses after its lease and is taken over by a retry."""

from __future__ import annotations

import secrets
from datetime import timedelta

import httpx
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import select, update

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.api.idempotency import Idempotency
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.idempotency import IdempotentRequest
from tests.service.helpers import CORRIDOR_NEXT_STATE, make_task
from tests.service.live import serving


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


def unrecorded_claim(
    client: TestClient, auth: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> dict[str, str]:
    """POST with a key whose response is sent (201) but never recorded, as when the database drops in between;
    returns the headers to retry with."""
    headers = auth | {"Idempotency-Key": f"dropped-{secrets.token_hex(4)}"}
    with monkeypatch.context() as patched:
        patched.setattr(Idempotency, "_finish", staticmethod(lambda *args: None))
        assert client.post("/v1/demonstrators", json={"name": "p"}, headers=headers).status_code == 201
    return headers


def lapse_leases(client: TestClient) -> None:
    """Move every running claim's lease into the past, as if ``idempotency_lease_s`` had passed."""
    with client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
        session.execute(
            update(IdempotentRequest)
            .where(IdempotentRequest.status.is_(None))
            .values(leased_until=utcnow() - timedelta(seconds=1))
        )
        session.commit()


def test_a_claim_within_its_lease_answers_409(
    client: TestClient, auth: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    headers = unrecorded_claim(client, auth, monkeypatch)
    retry = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    assert retry.status_code == 409 and "still being processed" in retry.json()["detail"]
    assert count_demonstrators(client, auth) == 1


def test_a_claim_whose_lease_lapsed_is_taken_over_by_the_retry(
    client: TestClient, auth: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    headers = unrecorded_claim(client, auth, monkeypatch)
    lapse_leases(client)
    retry = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    assert retry.status_code == 201 and "idempotent-replayed" not in retry.headers
    again = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    assert again.status_code == 201 and again.headers["idempotent-replayed"] == "true"
    assert again.json() == retry.json()
    assert (
        count_demonstrators(client, auth) == 2
    )  # the first run's demonstrator was committed before the drop
    changed = client.post("/v1/demonstrators", json={"name": "q"}, headers=headers)
    assert changed.status_code == 422  # a lapsed claim is taken over only by the same request


def test_only_the_request_holding_a_claim_renews_records_or_releases_it(
    client: TestClient, auth: dict[str, str], settings: Settings, monkeypatch: pytest.MonkeyPatch
) -> None:
    headers = unrecorded_claim(client, auth, monkeypatch)
    lapse_leases(client)
    makers = client.app.state.sessionmaker  # type: ignore[attr-defined]

    def claim_row() -> IdempotentRequest:
        """The key's row as stored now."""
        with makers() as session:
            return session.execute(
                select(IdempotentRequest).where(IdempotentRequest.key == headers["Idempotency-Key"])
            ).scalar_one()

    row = claim_row()
    assert row.status is None and row.claim is not None
    middleware = Idempotency(client.app, settings=settings)
    assert not middleware.renew(makers, row.lab_id, row.key, "another-request")
    assert claim_row().leased_until == row.leased_until
    for status in (201, 500):  # neither a response nor a release from a request that lost the claim
        Idempotency._finish(
            makers, row.lab_id, row.key, "another-request", {"status": status, "headers": [], "body": b"{}"}
        )
        assert (claim_row().status, claim_row().claim) == (None, row.claim)
    assert middleware.renew(makers, row.lab_id, row.key, row.claim)
    renewed = claim_row().leased_until
    assert renewed is not None and renewed > utcnow()
    retry = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    assert retry.status_code == 409  # renewed: its request is alive


def test_a_retry_sent_as_soon_as_the_answer_arrives_is_replayed(app: FastAPI, auth: dict[str, str]) -> None:
    # A generous timeout: the race is the point, not the latency of 400 writes on a busy machine.
    with serving(app) as url, httpx.Client(base_url=url, headers=auth, timeout=60) as http:
        statuses = []
        for attempt in range(200):
            headers = {"Idempotency-Key": f"race-{attempt}"}
            first = http.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
            again = http.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
            assert first.status_code == 201, first.text
            statuses.append(again.status_code)
            assert again.status_code != 201 or again.json()["id"] == first.json()["id"]
    assert statuses.count(409) == 0 and set(statuses) == {201}


def test_replaying_the_post_of_a_deleted_demonstrator_creates_anew(
    client: TestClient, auth: dict[str, str]
) -> None:
    headers = auth | {"Idempotency-Key": "made-then-deleted"}
    first = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    assert client.delete(f"/v1/demonstrators/{first.json()['id']}", headers=auth).status_code == 204
    again = client.post("/v1/demonstrators", json={"name": "p"}, headers=headers)
    assert again.status_code == 201 and "idempotent-replayed" not in again.headers
    assert again.json()["id"] != first.json()["id"]
    assert client.get(f"/v1/demonstrators/{again.json()['id']}", headers=auth).status_code == 200
