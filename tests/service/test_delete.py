"""Deleting (docs/api.md, "Deleting"): a demonstrator, task, demonstration batch, MDP or job goes with every row
and blob derived from it, counted table by table before and after; 409 while a job on it is queued or running
or while an MDP is used; another lab gets 404 (and `test_isolation` checks that for every route)."""

from __future__ import annotations

import secrets
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import func, select

from metairl_engine.sim.patient import PatientSettings, simulate_patient
from service.jobs.transitions import cancel
from service.settings import Settings
from service.store.models import Base
from service.store.models.base import utcnow
from service.store.models.jobs import Job
from service.store.models.webhooks import WebhookDelivery
from tests.service.helpers import (
    PUBLIC_HOOK,
    add_demonstrations,
    created,
    fitted_job,
    make_demonstrator,
    make_mdp,
    make_task,
    store_results,
)

RIGHT = [{"states": [0, 1, 2], "actions": [1, 1]}]
LEFT = [{"states": [2, 1, 0], "actions": [0, 0]}]


def row_counts(app: FastAPI) -> dict[str, int]:
    """Rows in every table of the database (the tests of a session run one at a time)."""
    with app.state.sessionmaker() as session:
        return {
            name: session.execute(select(func.count()).select_from(table)).scalar_one()
            for name, table in Base.metadata.tables.items()
        }


def diff(after: dict[str, int], before: dict[str, int]) -> dict[str, int]:
    """Tables whose row count changed, with the change."""
    return {t: after[t] - before[t] for t in before if after[t] != before[t]}


def upload_recording(client: TestClient, auth: dict[str, str], dem_id: str) -> dict[str, Any]:
    """A short COP recording (8×8 plate grid, one direction) of the demonstrator, with its velocity grid."""
    rec = simulate_patient(PatientSettings(width=8, height=8, repetitions=1, directions=("forward",)))
    session = rec.sessions["stimulated"]
    assert session.instruction is not None
    samples = [
        {"t": float(t), "x": float(x), "y": float(y), "instruction": str(i)}
        for t, x, y, i in zip(session.t, session.x, session.y, session.instruction, strict=True)
        if np.isfinite(x) and np.isfinite(y)
    ]
    body = {"kind": "grid", "name": "plate", "width": 8, "height": 8, "velocity": True, "gamma": 0.9}
    mdp_id = created(client.post("/v1/mdps", json=body, headers=auth))["id"]
    bounds = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
    out = created(
        client.post(
            f"/v1/demonstrators/{dem_id}/recordings",
            json={"bounds": bounds, "samples": samples, "mdp_id": mdp_id},
            headers=auth,
        )
    )
    return out | {"mdp_id": mdp_id}


def test_deleting_a_demonstrator_then_its_mdps_leaves_no_row_and_no_blob(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    before = row_counts(app)
    mdp = make_mdp(client, auth)
    fitted = fitted_job(
        app,
        client,
        auth,
        mdp=mdp,
        demonstrations={"right": RIGHT, "left": LEFT},
        rewards=np.arange(9, dtype=np.float32).reshape(3, 3),
    )
    dem_id = fitted["demonstrator_id"]
    task_id = fitted["task_ids"][0]
    created(client.put(f"/v1/tasks/{task_id}/true-reward", json={"values": [0, 1, 2]}, headers=auth), 200)
    recording = upload_recording(client, auth, dem_id)
    grown = diff(row_counts(app), before)
    for table in (
        "mdps",
        "tasks",
        "demonstrations",
        "true_rewards",
        "recordings",
        "jobs",
        "job_events",
        "job_step_histories",
    ):
        assert grown.get(table, 0) > 0, (table, grown)
    assert grown["rewards"] == 3 and grown["blobs"] > 10

    assert client.delete(f"/v1/mdps/{mdp['id']}", headers=auth).status_code == 409  # tasks use it
    response = client.delete(f"/v1/demonstrators/{dem_id}", headers=auth)
    assert response.status_code == 204, response.text
    assert response.content == b""
    for path in (
        f"/v1/demonstrators/{dem_id}",
        f"/v1/tasks/{task_id}",
        f"/v1/jobs/{fitted['job_id']}",
        f"/v1/rewards/{fitted['reward_ids'][0]}",
        f"/v1/tasks/{task_id}/true-reward",
    ):
        assert client.get(path, headers=auth).status_code == 404, path
    left = diff(row_counts(app), before)
    assert left == {"mdps": 2, "blobs": left["blobs"]}, left  # only the two MDPs and their arrays

    for mdp_id in (mdp["id"], recording["mdp_id"]):
        assert client.delete(f"/v1/mdps/{mdp_id}", headers=auth).status_code == 204
        assert client.get(f"/v1/mdps/{mdp_id}", headers=auth).status_code == 404
    assert row_counts(app) == before
    assert client.delete(f"/v1/demonstrators/{dem_id}", headers=auth).status_code == 404


def test_an_mdp_in_use_is_refused_naming_its_tasks_and_recordings_as_a_lab_knows_them(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth, name="patient 7")
    recording = upload_recording(client, auth, dem["id"])
    response = client.delete(f"/v1/mdps/{recording['mdp_id']}", headers=auth)
    assert response.status_code == 409, response.text
    detail = response.json()["detail"]
    tasks = client.get(f"/v1/demonstrators/{dem['id']}/tasks", headers=auth).json()["data"]
    assert f"task 'forward' ({tasks[0]['id']}) of demonstrator 'patient 7'" in detail
    assert f"recording ({recording['id']}) of demonstrator 'patient 7'" in detail


def test_a_queued_or_running_job_blocks_deleting_it_and_its_inputs(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    job = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )
    assert job["status"] == "queued"
    for path in (
        f"/v1/jobs/{job['id']}",
        f"/v1/tasks/{task['id']}",
        f"/v1/demonstrators/{task['demonstrator_id']}",
    ):
        response = client.delete(path, headers=auth)
        assert response.status_code == 409, (path, response.text)
        assert response.headers["content-type"].startswith("application/problem+json")
        assert job["id"] in response.json()["detail"] and "cancel" in response.json()["detail"]
    response = client.delete(f"/v1/mdps/{task['mdp_id']}", headers=auth)
    assert response.status_code == 409 and task["id"] in response.json()["detail"]
    assert client.get(f"/v1/jobs/{job['id']}", headers=auth).json()["status"] == "queued"

    created(client.post(f"/v1/jobs/{job['id']}/cancel", headers=auth), 202)
    before = row_counts(app)
    assert client.delete(f"/v1/jobs/{job['id']}", headers=auth).status_code == 204
    assert diff(row_counts(app), before) == {"jobs": -1, "job_events": -2}
    assert client.get(f"/v1/tasks/{task['id']}", headers=auth).json()["n_trajectories"] == 2


def test_deleting_a_task_takes_the_jobs_that_fitted_it_and_nothing_else(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = make_mdp(client, auth)
    rewards = np.arange(6, dtype=np.float32).reshape(2, 3)
    first = fitted_job(app, client, auth, mdp=mdp, demonstrations={"right": RIGHT}, rewards=rewards)
    dem_id = first["demonstrator_id"]
    other = make_task(client, auth, demonstrator_id=dem_id, mdp_id=mdp["id"])
    add_demonstrations(client, auth, other["id"], LEFT)
    second = created(
        client.post("/v1/jobs", json={"demonstrator_id": dem_id, "task_ids": [other["id"]]}, headers=auth),
        202,
    )
    created(client.post(f"/v1/jobs/{second['id']}/cancel", headers=auth), 202)
    before = row_counts(app)

    assert client.delete(f"/v1/tasks/{first['task_ids'][0]}", headers=auth).status_code == 204
    changed = diff(row_counts(app), before)
    assert changed["tasks"] == -1 and changed["demonstrations"] == -1 and changed["jobs"] == -1
    assert changed["rewards"] == -2 and changed["blobs"] == -(
        3 + 4
    )  # a batch: 3 arrays; rewards: 1 + 3 (value, policy)
    assert client.get(f"/v1/jobs/{first['job_id']}", headers=auth).status_code == 404
    assert client.get(f"/v1/jobs/{second['id']}", headers=auth).status_code == 200
    assert client.get(f"/v1/tasks/{other['id']}", headers=auth).json()["n_trajectories"] == 1
    assert client.get(f"/v1/demonstrators/{dem_id}", headers=auth).status_code == 200


def test_deleting_a_finished_job_keeps_its_inputs(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = make_mdp(client, auth)
    rewards = np.arange(6, dtype=np.float32).reshape(2, 3)
    fitted = fitted_job(app, client, auth, mdp=mdp, demonstrations={"right": RIGHT}, rewards=rewards)
    before = row_counts(app)
    assert client.delete(f"/v1/jobs/{fitted['job_id']}", headers=auth).status_code == 204
    changed = diff(row_counts(app), before)
    assert changed == {
        "jobs": -1,
        "job_events": changed["job_events"],
        "job_step_histories": -1,
        "rewards": -2,
        "blobs": -4,
    }, changed
    assert client.get(f"/v1/rewards/{fitted['reward_ids'][1]}", headers=auth).status_code == 404
    assert client.get(f"/v1/tasks/{fitted['task_ids'][0]}", headers=auth).json()["n_trajectories"] == 1


def test_another_labs_resources_cannot_be_deleted(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    task = make_task(client, auth)
    for path in (
        f"/v1/tasks/{task['id']}",
        f"/v1/demonstrators/{task['demonstrator_id']}",
        f"/v1/mdps/{task['mdp_id']}",
    ):
        assert client.delete(path, headers=auth_b).status_code == 404
        assert client.get(path, headers=auth).status_code == 200


def test_delete_routes_are_documented(app: FastAPI) -> None:
    paths = app.openapi()["paths"]
    for path in (
        "/v1/demonstrators/{demonstrator_id}",
        "/v1/tasks/{task_id}",
        "/v1/mdps/{mdp_id}",
        "/v1/jobs/{job_id}",
        "/v1/tasks/{task_id}/demonstrations/{batch_id}",
    ):
        responses = paths[path]["delete"]["responses"]
        assert {"204", "404", "409"} <= set(responses), (path, responses)


def test_a_deleted_demonstrator_leaves_no_trace_in_sqlite_files(
    backend: str, settings: Settings, client: TestClient, auth: dict[str, str]
) -> None:
    if backend != "sqlite":
        pytest.skip("SQLite's files only")
    marker = f"withdrawn-{secrets.token_hex(8)}"
    demonstrator = created(client.post("/v1/demonstrators", json={"name": marker}, headers=auth))
    path = Path(str(settings.database_url).removeprefix("sqlite:///"))
    files = [path, path.with_name(path.name + "-wal")]
    assert any(marker.encode() in f.read_bytes() for f in files if f.exists())
    assert client.delete(f"/v1/demonstrators/{demonstrator['id']}", headers=auth).status_code == 204
    assert not any(marker.encode() in f.read_bytes() for f in files if f.exists())


def test_deleting_a_job_drops_its_webhook_deliveries(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth))
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"], RIGHT)
    job = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )
    with app.state.sessionmaker() as session:
        cancel(session, session.get_one(Job, job["id"]))
        session.commit()
        assert session.execute(select(WebhookDelivery).where(WebhookDelivery.job_id == job["id"])).first()
    assert client.delete(f"/v1/jobs/{job['id']}", headers=auth).status_code == 204
    with app.state.sessionmaker() as session:
        assert not session.execute(select(WebhookDelivery).where(WebhookDelivery.job_id == job["id"])).first()


def finished_now(app: FastAPI, job_id: str) -> None:
    """Stamp a job's finish time now, as the worker does when it ends (`store_results` leaves it unset)."""
    with app.state.sessionmaker() as session:
        session.get_one(Job, job_id).finished_at = utcnow()
        session.commit()


def test_deleting_a_batch_takes_its_arrays_and_leaves_the_task_and_its_other_batches(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    kept = add_demonstrations(client, auth, task["id"], RIGHT)
    gone = add_demonstrations(client, auth, task["id"], LEFT)
    before = row_counts(app)
    url = f"/v1/tasks/{task['id']}/demonstrations/{gone['id']}"
    response = client.delete(url, headers=auth)
    assert response.status_code == 204 and response.content == b"", response.text
    assert diff(row_counts(app), before) == {"demonstrations": -1, "blobs": -3}  # states, actions, lengths
    assert client.get(url, headers=auth).status_code == 404
    listed = client.get(f"/v1/tasks/{task['id']}/demonstrations", headers=auth).json()["data"]
    assert [b["id"] for b in listed] == [kept["id"]]
    assert client.get(f"/v1/tasks/{task['id']}", headers=auth).json()["n_trajectories"] == 1
    assert client.delete(url, headers=auth).status_code == 404


def test_a_deleted_batchs_idempotency_key_creates_a_new_batch_instead_of_answering_the_deleted_id(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    url, headers = f"/v1/tasks/{task['id']}/demonstrations", auth | {"Idempotency-Key": "batch-of-monday"}
    first = created(client.post(url, json={"trajectories": RIGHT}, headers=headers))
    assert client.post(url, json={"trajectories": RIGHT}, headers=headers).json()["id"] == first["id"]
    assert client.delete(f"{url}/{first['id']}", headers=auth).status_code == 204
    again = client.post(url, json={"trajectories": RIGHT}, headers=headers)
    assert again.status_code == 201 and "Idempotent-Replayed" not in again.headers
    assert again.json()["id"] != first["id"]
    assert client.get(f"{url}/{again.json()['id']}", headers=auth).status_code == 200


def test_a_queued_job_fitting_the_task_blocks_deleting_its_batch_and_a_job_on_another_task_does_not(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    dem_id = task["demonstrator_id"]
    other = make_task(client, auth, demonstrator_id=dem_id, mdp_id=task["mdp_id"])
    batch = add_demonstrations(client, auth, task["id"], RIGHT)
    add_demonstrations(client, auth, other["id"], LEFT)
    jobs = [
        created(client.post("/v1/jobs", json={"demonstrator_id": dem_id, "task_ids": [t]}, headers=auth), 202)
        for t in (task["id"], other["id"])
    ]
    url = f"/v1/tasks/{task['id']}/demonstrations/{batch['id']}"
    before = row_counts(app)
    refused = client.delete(url, headers=auth)
    assert refused.status_code == 409, refused.text
    assert refused.headers["content-type"].startswith("application/problem+json")
    detail = refused.json()["detail"]
    assert batch["id"] in detail and jobs[0]["id"] in detail and "cancel" in detail
    assert jobs[1]["id"] not in detail
    assert row_counts(app) == before  # nothing deleted
    assert client.get(url, headers=auth).status_code == 200

    created(client.post(f"/v1/jobs/{jobs[0]['id']}/cancel", headers=auth), 202)
    assert client.delete(url, headers=auth).status_code == 204  # the other task's job is still queued
    assert client.get(f"/v1/jobs/{jobs[0]['id']}", headers=auth).status_code == 404  # ended after the upload
    assert client.get(f"/v1/jobs/{jobs[1]['id']}", headers=auth).json()["status"] == "queued"


def test_deleting_a_batch_takes_the_jobs_that_finished_after_its_upload_and_keeps_earlier_ones(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = make_mdp(client, auth)
    rewards = np.arange(6, dtype=np.float32).reshape(2, 3)
    earlier = fitted_job(app, client, auth, mdp=mdp, demonstrations={"right": RIGHT}, rewards=rewards)
    finished_now(app, earlier["job_id"])
    task_id, dem_id = earlier["task_ids"][0], earlier["demonstrator_id"]
    first_batch = client.get(f"/v1/tasks/{task_id}/demonstrations", headers=auth).json()["data"][0]
    batch = add_demonstrations(client, auth, task_id, LEFT)
    later = created(client.post("/v1/jobs", json={"demonstrator_id": dem_id}, headers=auth), 202)
    later_rewards = store_results(
        app, job_id=later["id"], baseline=rewards[0], task_rewards=[rewards[1]], n_actions=2
    )
    finished_now(app, later["id"])

    before = row_counts(app)
    assert client.delete(f"/v1/tasks/{task_id}/demonstrations/{batch['id']}", headers=auth).status_code == 204
    changed = diff(row_counts(app), before)
    assert changed["demonstrations"] == -1 and changed["jobs"] == -1 and changed["rewards"] == -2, changed
    assert changed["blobs"] == -(3 + 4), changed  # the batch's 3 arrays; rewards: 1 + 3 (value, policy)
    assert client.get(f"/v1/jobs/{later['id']}", headers=auth).status_code == 404
    assert client.get(f"/v1/rewards/{later_rewards[1]}", headers=auth).status_code == 404
    assert client.get(f"/v1/jobs/{earlier['job_id']}", headers=auth).json()["status"] == "succeeded"
    assert client.get(f"/v1/rewards/{earlier['reward_ids'][1]}", headers=auth).status_code == 200

    # The earlier job read the first batch: it goes with that one.
    url = f"/v1/tasks/{task_id}/demonstrations/{first_batch['id']}"
    assert client.delete(url, headers=auth).status_code == 204
    assert client.get(f"/v1/jobs/{earlier['job_id']}", headers=auth).status_code == 404
    assert client.get(f"/v1/tasks/{task_id}", headers=auth).json()["n_trajectories"] == 0


def test_deleting_a_batch_a_recording_stored_keeps_the_recording_which_no_longer_names_it(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    recording = upload_recording(client, auth, dem["id"])
    (entry,) = recording["tasks"]
    cut = client.get(f"/v1/recordings/{recording['id']}/demonstrations", headers=auth).json()["trajectories"]
    assert {t["demonstration_id"] for t in cut} == {entry["demonstration_id"]}
    before = row_counts(app)
    url = f"/v1/tasks/{entry['task_id']}/demonstrations/{entry['demonstration_id']}"
    assert client.delete(url, headers=auth).status_code == 204
    assert diff(row_counts(app), before) == {"demonstrations": -1, "blobs": -3}  # samples and recording stay
    (listed,) = client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"]
    assert listed["tasks"] == [entry | {"demonstration_id": None}]
    assert (listed["n_samples"], listed["segments"]) == (recording["n_samples"], recording["segments"])
    cut = client.get(f"/v1/recordings/{recording['id']}/demonstrations", headers=auth).json()["trajectories"]
    assert cut == []
