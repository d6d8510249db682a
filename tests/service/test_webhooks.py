"""`/v1/webhooks` without a worker: subscribe (secret shown once), list, read, delete; targets refused;
other labs get 404; a delivery is written with the job's final status, and its signature verifies."""

from __future__ import annotations

import base64
import json
import time

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from standardwebhooks import Webhook as Verifier
from standardwebhooks.webhooks import WebhookVerificationError

from service.api.app import create_app
from service.jobs.transitions import claim, transition
from service.jobs.webhooks import private_address, sign
from service.settings import Settings
from service.store.models.job_status import JobStatus
from service.store.models.webhooks import WebhookDelivery
from tests.service.helpers import PUBLIC_HOOK, add_demonstrations, created, make_task


def test_create_list_read_and_delete_a_webhook(client: TestClient, auth: dict[str, str]) -> None:
    response = client.post("/v1/webhooks", json={"url": PUBLIC_HOOK, "events": ["job.failed"]}, headers=auth)
    hook = created(response)
    assert hook["id"].startswith("whk_") and response.headers["location"] == f"/v1/webhooks/{hook['id']}"
    assert hook["secret"].startswith("whsec_") and len(base64.b64decode(hook["secret"][6:])) == 32
    assert (hook["url"], hook["events"], hook["deliveries"]) == (PUBLIC_HOOK, ["job.failed"], [])

    read = created(client.get(f"/v1/webhooks/{hook['id']}", headers=auth), 200)
    assert "secret" not in read and read["url"] == PUBLIC_HOOK
    listed = created(client.get("/v1/webhooks", headers=auth), 200)["data"]
    assert [h["id"] for h in listed] == [hook["id"]] and "secret" not in listed[0]
    default = created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth))
    assert default["events"] == ["job.cancelled", "job.failed", "job.succeeded"]

    assert client.delete(f"/v1/webhooks/{hook['id']}", headers=auth).status_code == 204
    assert client.get(f"/v1/webhooks/{hook['id']}", headers=auth).status_code == 404


@pytest.mark.parametrize(
    ("url", "pointer_says"),
    [
        ("http://127.0.0.1:8080/hook", "loopback"),
        ("http://localhost/hook", "loopback"),
        ("https://10.1.2.3/hook", "private"),
        ("http://169.254.169.254/latest/meta-data", "link-local"),
        ("http://[::1]/hook", "loopback"),
        ("ftp://93.184.215.14/hook", "http"),
        ("not a url", "http"),
        ("https://user:pw@93.184.215.14/hook", "password"),
    ],
)
def test_private_loopback_and_odd_targets_are_refused(
    client: TestClient, auth: dict[str, str], url: str, pointer_says: str
) -> None:
    response = client.post("/v1/webhooks", json={"url": url}, headers=auth)
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["errors"][0]["pointer"] == "/url" and pointer_says in problem["errors"][0]["message"]


def test_unknown_events_are_refused(client: TestClient, auth: dict[str, str]) -> None:
    response = client.post("/v1/webhooks", json={"url": PUBLIC_HOOK, "events": ["job.started"]}, headers=auth)
    assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == "/events/0"


def test_an_unknown_event_and_a_private_target_come_in_one_answer(
    client: TestClient, auth: dict[str, str]
) -> None:
    body = {"url": "http://127.0.0.1:8080/hook", "events": ["job.started"], "secret": "mine"}
    response = client.post("/v1/webhooks", json=body, headers=auth)
    assert response.status_code == 422, response.text
    errors = response.json()["errors"]
    assert [e["pointer"] for e in errors] == ["/events/0", "/secret", "/url"]
    assert "loopback" in errors[2]["message"]
    assert client.get("/v1/webhooks", headers=auth).json()["data"] == []


def test_the_operator_may_allow_private_targets(settings: Settings) -> None:
    from tests.conftest import _new_key

    app = create_app(settings.model_copy(update={"webhook_allow_private": True}))
    try:
        with TestClient(app) as client:
            auth = {"Authorization": f"Bearer {_new_key(app, 'lab-private')}"}
            created(client.post("/v1/webhooks", json={"url": "http://127.0.0.1:9/hook"}, headers=auth))
    finally:
        app.state.engine.dispose()


def test_another_lab_gets_404_and_sees_none(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    hook = created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth))
    for method in ("GET", "DELETE"):
        response = client.request(method, f"/v1/webhooks/{hook['id']}", headers=auth_b)
        assert (
            response.status_code == 404 and response.json()["detail"] == f"No webhook with id {hook['id']!r}."
        )
    assert created(client.get("/v1/webhooks", headers=auth_b), 200)["data"] == []
    assert client.get(f"/v1/webhooks/{hook['id']}", headers=auth).status_code == 200


def test_a_delivery_is_written_with_the_final_status_and_its_signature_verifies(
    app: FastAPI, client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    wanted = created(
        client.post("/v1/webhooks", json={"url": PUBLIC_HOOK, "events": ["job.cancelled"]}, headers=auth)
    )
    created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK, "events": ["job.succeeded"]}, headers=auth))
    created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth_b))  # another lab's
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    job_id = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )["id"]
    with app.state.sessionmaker() as session:  # a running job: cancelling it is not yet its end
        claim(session, job_id)
        session.commit()
    created(client.post(f"/v1/jobs/{job_id}/cancel", headers=auth), 202)
    assert created(client.get(f"/v1/webhooks/{wanted['id']}", headers=auth), 200)["deliveries"] == []
    with app.state.sessionmaker() as session:  # the worker stops: the job ends as cancelled
        transition(session, job_id, JobStatus.RUNNING, JobStatus.CANCELLED, message="cancelled on request")
        session.commit()

    deliveries = created(client.get(f"/v1/webhooks/{wanted['id']}", headers=auth), 200)["deliveries"]
    assert [(d["type"], d["job_id"], d["status"], d["attempts"]) for d in deliveries] == [
        ("job.cancelled", job_id, "pending", 0)
    ]
    with app.state.sessionmaker() as session:
        rows = session.query(WebhookDelivery).filter(WebhookDelivery.job_id == job_id).all()
        assert len(rows) == 1  # not the job.succeeded webhook, not the other lab's
        payload = rows[0].payload
    assert payload["type"] == "job.cancelled"
    assert payload["data"] == created(client.get(f"/v1/jobs/{job_id}", headers=auth), 200)
    body, now = json.dumps(payload).encode(), int(time.time())
    headers = {
        "webhook-id": rows[0].id,
        "webhook-timestamp": str(now),
        "webhook-signature": sign(wanted["secret"], msg_id=rows[0].id, timestamp=now, body=body),
    }
    assert Verifier(wanted["secret"]).verify(body, headers) == payload
    with pytest.raises(WebhookVerificationError):
        Verifier(wanted["secret"]).verify(body + b" ", headers)


@pytest.mark.parametrize(
    "url",
    [
        "http://[::127.0.0.1]/hook",  # IPv4-compatible
        "http://[::ffff:127.0.0.1]/hook",  # IPv4-mapped
        "http://[64:ff9b::7f00:1]/hook",  # NAT64 of 127.0.0.1
        "http://[64:ff9b::a9fe:a9fe]/hook",  # NAT64 of 169.254.169.254
        "http://[64:ff9b:1::1]/hook",  # local-use NAT64
        "http://[2002:7f00:1::]/hook",  # 6to4 of 127.0.0.1
        "http://[2002:a9fe:a9fe::]/hook",  # 6to4 of 169.254.169.254
        "http://[fec0::1]/hook",  # site-local
        "http://[2001::1]/hook",  # Teredo
        "http://[fd00::1]/hook",  # unique local
        "http://[100::1]/hook",  # discard-only
    ],
)
def test_special_use_ipv6_targets_are_refused(client: TestClient, auth: dict[str, str], url: str) -> None:
    response = client.post("/v1/webhooks", json={"url": url}, headers=auth)
    assert response.status_code == 422, response.text
    assert "special-use" in response.json()["errors"][0]["message"]


@pytest.mark.parametrize(
    "address", ["64:ff9b::808:808", "2002:808:808::1", "2606:4700:4700::1111", "::ffff:8.8.8.8", "8.8.8.8"]
)
def test_public_addresses_and_those_embedding_one_are_allowed(address: str) -> None:
    assert not private_address(address)


def test_a_lab_has_at_most_the_configured_number_of_webhooks(settings: Settings) -> None:
    from tests.conftest import _new_key

    app = create_app(settings.model_copy(update={"webhook_max_per_lab": 3}))
    try:
        with TestClient(app) as client:
            auth = {"Authorization": f"Bearer {_new_key(app, 'lab-hooks')}"}
            other = {"Authorization": f"Bearer {_new_key(app, 'lab-other')}"}
            hooks = [
                created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth))
                for _ in range(3)
            ]
            refused = client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth)
            assert refused.status_code == 409 and "METAIRL_WEBHOOK_MAX_PER_LAB" in refused.json()["detail"]
            created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=other))
            assert client.delete(f"/v1/webhooks/{hooks[0]['id']}", headers=auth).status_code == 204
            created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth))
    finally:
        app.state.engine.dispose()
