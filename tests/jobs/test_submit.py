"""`POST /v1/jobs` checks, listing, cancelling queued jobs, idempotent retries and broker failures — API only.

Runs on the root fixtures' SQLite and PostgreSQL databases with the embedded broker (nothing consumes it).
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any, cast

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_engine.config import FitConfig
from metairl_engine.maxent import fit_maxent
from service.domain.job_config import SETTINGS_ONLY_WITH
from service.jobs.queue import CeleryJobQueue
from service.settings import Settings
from tests.engine.test_maxent import as_tasks, goal_tasks
from tests.jobs.helpers import QUICK, demonstrated_tasks, submit
from tests.service.helpers import add_demonstrations, make_demonstrator, make_mdp, make_task


def pointers(response: Any) -> list[str]:
    """The pointers of a 422 problem (asserting it is one)."""
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    return [e["pointer"] for e in response.json()["errors"]]


@pytest.mark.parametrize(
    ("config", "pointer"),
    [
        ({"max_steps": 0}, "/config/max_steps"),
        ({"max_stepz": 10}, "/config/max_stepz"),
        ({"max_steps": "ten"}, "/config/max_steps"),
        ({"max_steps": 10.5}, "/config/max_steps"),
        ({"learning_rate": True}, "/config/learning_rate"),
        ({"hidden": [8, "x"]}, "/config/hidden/1"),
        ({"sharing": "cosine"}, "/config/sharing"),
        ({"holdout_fraction": 1.0}, "/config/holdout_fraction"),
        ({"hidden": [100_000, 100_000]}, "/config/hidden/0"),  # over METAIRL_MAX_HIDDEN_UNITS' default
    ],
)
def test_bad_config_is_422_naming_the_field_and_creates_no_job(
    client: TestClient, auth: dict[str, str], config: dict[str, Any], pointer: str
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    response = client.post(
        "/v1/jobs", json={"demonstrator_id": demonstrator_id, "config": config}, headers=auth
    )
    assert pointer in pointers(response)
    assert pointer in response.json()["detail"]
    assert client.get("/v1/jobs", headers=auth).json()["data"] == []


def test_submitted_job_is_queued_with_every_setting_filled_in(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, task_ids = demonstrated_tasks(client, auth)
    job = submit(client, auth, demonstrator_id, {"max_steps": 7, "hidden": [4, 2]})
    assert job["id"].startswith("job_")
    assert job["status"] == "queued"
    assert job["task_ids"] == task_ids
    assert job["config"] == FitConfig(max_steps=7, hidden=(4, 2)).to_dict()
    assert (job["attempts"], job["progress"], job["error"], job["cancel_requested"]) == (0, None, None, False)
    assert client.get(f"/v1/jobs/{job['id']}", headers=auth).json() == job
    events = client.get(f"/v1/jobs/{job['id']}/events", headers=auth).json()
    assert [(e["kind"], e["status"]) for e in events["data"]] == [("status", "queued")]


def test_tasks_must_belong_to_the_demonstrator_and_appear_once(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, task_ids = demonstrated_tasks(client, auth)
    _, others = demonstrated_tasks(client, auth, 1)
    body = {
        "demonstrator_id": demonstrator_id,
        "task_ids": [task_ids[0], others[0], task_ids[0], "task_nope"],
    }
    assert pointers(client.post("/v1/jobs", json=body, headers=auth)) == [
        "/task_ids/1",
        "/task_ids/2",
        "/task_ids/3",
    ]


def test_a_bad_setting_and_a_bad_task_come_in_one_answer(client: TestClient, auth: dict[str, str]) -> None:
    demonstrator_id, task_ids = demonstrated_tasks(client, auth, 1)
    body = {
        "demonstrator_id": demonstrator_id,
        "task_ids": [task_ids[0], "task_nope"],
        "config": {"baseline_features": [0, 0]},  # passes the schema, not the engine's check
    }
    response = client.post("/v1/jobs", json=body, headers=auth)
    assert response.status_code == 422, response.text
    assert pointers(response) == ["/config/baseline_features", "/task_ids/1"]


def test_what_the_schema_refuses_and_what_only_the_checks_after_it_find_come_in_one_answer(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, task_ids = demonstrated_tasks(client, auth, 1)
    config = {
        "hidden": "wide",  # not a list
        "learning_rate": "fast",  # not a number
        "max_stepz": 10,  # not a setting
        "holdout_fraction": 1.0,  # out of range
        "baseline_features": [0, 0],  # of the schema's type, refused by the engine's check
    }
    body = {"demonstrator_id": demonstrator_id, "task_ids": [task_ids[0], "task_nope"], "config": config}
    response = client.post("/v1/jobs", json=body, headers=auth)
    assert sorted(pointers(response)) == [
        "/config/baseline_features",
        "/config/hidden",
        "/config/holdout_fraction",
        "/config/learning_rate",
        "/config/max_stepz",
        "/task_ids/1",
    ]
    assert client.get("/v1/jobs", headers=auth).json()["data"] == []


def test_a_bad_setting_and_hidden_layers_over_the_size_limit_come_in_one_answer(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    config = {"learning_rate": "fast", "hidden": [8, 100_000, 100_000]}  # over METAIRL_MAX_HIDDEN_UNITS
    response = client.post(
        "/v1/jobs", json={"demonstrator_id": demonstrator_id, "config": config}, headers=auth
    )
    assert pointers(response) == ["/config/learning_rate", "/config/hidden/1", "/config/hidden/2"]
    assert "METAIRL_MAX_HIDDEN_UNITS" in response.json()["errors"][1]["message"]


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ({"demonstrator_id": 5, "config": {"seed": -1}}, ["/demonstrator_id", "/config/seed"]),
        ({"config": {"hidden": [100_000]}}, ["/demonstrator_id", "/config/hidden/0"]),
        (
            {"demonstrator_id": "dem_nope", "task_id": [], "config": {"sharing": "cosine"}},
            ["/task_id", "/config/sharing"],
        ),
        ({"demonstrator_id": "dem_nope", "config": "fast"}, ["/config", "/demonstrator_id"]),
    ],
)
def test_a_mistake_in_the_body_itself_comes_with_the_configs(
    client: TestClient, auth: dict[str, str], body: dict[str, Any], expected: list[str]
) -> None:
    assert pointers(client.post("/v1/jobs", json=body, headers=auth)) == expected


def test_a_body_that_is_not_an_object_is_422_at_the_body(client: TestClient, auth: dict[str, str]) -> None:
    assert pointers(client.post("/v1/jobs", json=["dem_x"], headers=auth)) == [""]


def test_every_task_needs_demonstrations(client: TestClient, auth: dict[str, str]) -> None:
    demonstrator_id, task_ids = demonstrated_tasks(client, auth, 1)
    bare = make_task(client, auth, demonstrator_id=demonstrator_id)["id"]
    response = client.post(
        "/v1/jobs", json={"demonstrator_id": demonstrator_id, "task_ids": [task_ids[0], bare]}, headers=auth
    )
    assert pointers(response) == ["/task_ids/1"]
    assert "has no demonstrations" in response.json()["errors"][0]["message"]


def test_tasks_must_share_one_state_space(client: TestClient, auth: dict[str, str]) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    wider = make_mdp(
        client,
        auth,
        n_states=4,
        transitions={"kind": "deterministic", "next_state": [[0, 1], [0, 2], [1, 3], [2, 3]]},
        layout=None,
    )
    other = make_task(client, auth, demonstrator_id=demonstrator_id, mdp_id=wider["id"])["id"]
    add_demonstrations(client, auth, other)
    response = client.post("/v1/jobs", json={"demonstrator_id": demonstrator_id}, headers=auth)
    assert pointers(response) == ["/demonstrator_id"]
    assert "4 states" in response.json()["errors"][0]["message"]
    assert other in response.json()["errors"][0]["message"]


def test_unknown_or_other_labs_demonstrator_is_the_same_422(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    theirs = make_demonstrator(client, auth_b)["id"]
    for demonstrator_id in (theirs, "dem_nope"):
        response = client.post("/v1/jobs", json={"demonstrator_id": demonstrator_id}, headers=auth)
        assert pointers(response) == ["/demonstrator_id"]
        assert response.json()["errors"][0]["message"] == "no demonstrator with this id exists in your lab"


def test_other_labs_job_is_not_found_anywhere(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    job_id = submit(client, auth, demonstrator_id, QUICK)["id"]
    for method, path in [
        ("GET", f"/v1/jobs/{job_id}"),
        ("GET", f"/v1/jobs/{job_id}/events"),
        ("GET", f"/v1/jobs/{job_id}/rewards"),
        ("POST", f"/v1/jobs/{job_id}/cancel"),
    ]:
        assert client.request(method, path, headers=auth_b).status_code == 404, path
    assert client.get("/v1/jobs", headers=auth_b).json()["data"] == []
    assert client.get(f"/v1/jobs/{job_id}", headers=auth).json()["status"] == "queued"


def test_list_filters_by_status_and_demonstrator_with_cursor_pages(
    client: TestClient, auth: dict[str, str]
) -> None:
    first, _ = demonstrated_tasks(client, auth, 1)
    second, _ = demonstrated_tasks(client, auth, 1)
    ids = [submit(client, auth, dem, QUICK)["id"] for dem in (first, first, second)]
    client.post(f"/v1/jobs/{ids[0]}/cancel", headers=auth)

    def listed(**params: Any) -> list[str]:
        out: list[str] = []
        cursor = None
        while True:
            page = client.get(
                "/v1/jobs",
                params={**params, "limit": 1, **({"cursor": cursor} if cursor else {})},
                headers=auth,
            ).json()
            out += [j["id"] for j in page["data"]]
            if not page["has_more"]:
                return out
            cursor = page["next_cursor"]

    assert listed() == ids[::-1]
    assert listed(demonstrator_id=first) == ids[1::-1]
    assert listed(status="cancelled") == [ids[0]]
    assert listed(status="queued", demonstrator_id=first) == [ids[1]]
    assert listed(status=["cancelled", "queued"]) == ids[::-1]  # several statuses: any of them
    assert client.get("/v1/jobs", params={"status": "done"}, headers=auth).status_code == 422


def test_cancelling_a_queued_job_is_immediate_and_again_is_409(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    job_id = submit(client, auth, demonstrator_id, QUICK)["id"]
    response = client.post(f"/v1/jobs/{job_id}/cancel", headers=auth)
    assert response.status_code == 202
    assert response.json()["status"] == "cancelled"
    assert response.json()["finished_at"] is not None
    again = client.post(f"/v1/jobs/{job_id}/cancel", headers=auth)
    assert again.status_code == 409
    assert "already finished (cancelled)" in again.json()["detail"]
    rewards = client.get(f"/v1/jobs/{job_id}/rewards", headers=auth)
    assert rewards.status_code == 409


def test_same_idempotency_key_and_body_creates_one_job_and_sends_one_message(
    client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    body = {"demonstrator_id": demonstrator_id, "config": QUICK}
    headers = {**auth, "Idempotency-Key": "retry-me"}
    first = client.post("/v1/jobs", json=body, headers=headers)
    again = client.post("/v1/jobs", json=body, headers=headers)
    assert (first.status_code, again.status_code) == (202, 202)
    assert again.headers["idempotent-replayed"] == "true"
    assert again.json() == first.json() and again.headers["location"] == first.headers["location"]
    listed = client.get("/v1/jobs", params={"demonstrator_id": demonstrator_id}, headers=auth).json()
    assert [j["id"] for j in listed["data"]] == [first.json()["id"]]
    queue = CeleryJobQueue(settings)
    assert queue.waiting() == 1  # the real (embedded) broker holds exactly one message
    other = client.post("/v1/jobs", json=body, headers={**auth, "Idempotency-Key": "another"})
    assert other.json()["id"] != first.json()["id"] and queue.waiting() == 2


def test_broker_refusing_the_message_is_503_with_retry_after_and_stores_no_job(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    app.state.job_queue = CeleryJobQueue(settings.model_copy(update={"broker_url": "redis://127.0.0.1:1/0"}))
    demonstrator_id, task_ids = demonstrated_tasks(client, auth, 1)
    body = {"demonstrator_id": demonstrator_id, "task_ids": task_ids, "config": QUICK}
    refused = client.post("/v1/jobs", json=body, headers={**auth, "Idempotency-Key": "blip"})
    assert refused.status_code == 503, refused.text
    assert refused.headers["content-type"].startswith("application/problem+json")
    assert int(refused.headers["Retry-After"]) > 0
    assert "could not be handed to a worker" in refused.json()["detail"]
    assert "redis://127.0.0.1:1/0" in refused.json()["detail"]
    assert client.get("/v1/jobs", headers=auth).json()["data"] == []
    # The broker is back: the same request, same key, is queued (the 503 was not recorded for replay).
    app.state.job_queue = CeleryJobQueue(settings)
    accepted = client.post("/v1/jobs", json=body, headers={**auth, "Idempotency-Key": "blip"})
    assert accepted.status_code == 202 and accepted.json()["status"] == "queued"


@pytest.mark.parametrize(
    ("config", "accepted"),
    [
        ({"baseline_features": [0, 1]}, True),  # the corridor's layout gives x and y
        ({"baseline_features": [2]}, False),
        ({"baseline_features": [0], "tabular_inputs": "one_hot"}, False),  # one-hot inputs have no columns
    ],
)
def test_baseline_features_are_checked_against_the_mdp_at_submission(
    client: TestClient, auth: dict[str, str], config: dict[str, Any], accepted: bool
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    response = client.post(
        "/v1/jobs", json={"demonstrator_id": demonstrator_id, "config": config}, headers=auth
    )
    if accepted:
        assert response.status_code == 202, response.text
    else:
        assert pointers(response) == ["/config/baseline_features"]


def test_a_job_says_which_of_its_settings_another_setting_makes_the_fit_ignore(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    plain = submit(client, auth, demonstrator_id, QUICK)
    assert plain["ignored_settings"] == []
    odd = submit(client, auth, demonstrator_id, QUICK | {"bgi_k": 3, "sharing": "none", "sharing_weight": 9})
    assert odd["ignored_settings"] == [  # in the config's order of settings
        "sharing_weight is used only with sharing; this job has sharing 'none'",
        "bgi_k is used only with backup \"bgi\"; this job has backup 'max'",
    ]
    assert (
        client.get(f"/v1/jobs/{odd['id']}", headers=auth).json()["ignored_settings"]
        == odd["ignored_settings"]
    )


def test_a_tabular_job_is_told_which_of_its_settings_the_solver_ignores(
    client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    changed = QUICK | {"stay_at_ends": False, "sharing": "none", "sharing_weight": 9, "bgi_k": 3}
    alone = submit(client, auth, demonstrator_id, changed | {"method": "maxent"})
    networks_only = "is used only with method \"meta_irl\"; this job has method 'maxent'"
    assert alone["ignored_settings"] == [
        f"sharing {networks_only}",
        f"sharing_weight {networks_only}",
        'stay_at_ends is used only with method "meta_irl" or "shared_maxent"; this job has method \'maxent\'',
        f"bgi_k {networks_only}",
        f"hidden {networks_only}",
        f"patience {networks_only}",
    ]
    shared = submit(client, auth, demonstrator_id, changed | {"method": "shared_maxent"})
    assert shared["ignored_settings"] == [  # shared_maxent reads stay_at_ends
        f"{name} is used only with method \"meta_irl\"; this job has method 'shared_maxent'"
        for name in ("sharing", "sharing_weight", "bgi_k", "hidden", "patience")
    ]


@pytest.mark.parametrize("method", ["maxent", "shared_maxent"])
def test_the_settings_a_tabular_job_is_told_are_ignored_are_those_its_solver_never_reads(method: str) -> None:
    config = FitConfig(method=method, max_steps=3)  # type: ignore[arg-type]
    read: set[str] = set()

    class Recording:
        """``config``, noting the name of every setting read from it."""

        def __getattr__(self, name: str) -> Any:
            read.add(name)
            return getattr(config, name)

    sims, _ = goal_tasks(n_tasks=2, n_demos=3)
    fit_maxent(as_tasks(sims), cast(FitConfig, Recording()))
    said = {
        name
        for name, other, used_with, _ in SETTINGS_ONLY_WITH
        if other == "method" and used_with is not None and method not in used_with
    }
    assert said == {f.name for f in fields(FitConfig)} - read
