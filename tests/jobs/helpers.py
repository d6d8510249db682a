"""Helpers of the jobs tests: a demonstrator with demonstrated tasks, submitting and polling jobs."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from service.jobs.submit import create_job
from service.settings import Settings
from service.store.models.demonstrators import Demonstrator
from tests.service.helpers import add_demonstrations, created, make_demonstrator, make_mdp, make_task

QUICK: dict[str, Any] = {"max_steps": 30, "hidden": [8], "tolerance": 0, "patience": 0}
"""A job that finishes in about a second once a worker has it."""

RING_STATES = 150
"""States of the ring MDP of `ring_tasks`: large enough that a fit there takes thousands of steps."""

ENDLESS: dict[str, Any] = {
    "max_steps": 100_000,
    "hidden": [16],
    "sharing": "l2",
    "tolerance": 0,
    "patience": 0,
}
"""On `ring_tasks`: runs for many seconds (until the losses stop changing at all), so it gets cancelled first."""

LONG: dict[str, Any] = {**ENDLESS, "max_steps": 100}
"""On `ring_tasks`: a second to several seconds (by machine load), then succeeds."""

TERMINAL = {"succeeded", "failed", "cancelled"}


def demonstrated_tasks(client: TestClient, auth: dict[str, str], n_tasks: int = 2) -> tuple[str, list[str]]:
    """A demonstrator with ``n_tasks`` corridor tasks (one shared MDP), each with demonstrations."""
    demonstrator_id = make_demonstrator(client, auth)["id"]
    mdp_id = make_mdp(client, auth)["id"]
    task_ids = []
    for _ in range(n_tasks):
        task_id = make_task(client, auth, demonstrator_id=demonstrator_id, mdp_id=mdp_id)["id"]
        add_demonstrations(client, auth, task_id)
        task_ids.append(task_id)
    return demonstrator_id, task_ids


def ring_tasks(client: TestClient, auth: dict[str, str]) -> tuple[str, list[str]]:
    """A demonstrator with two tasks on a ring (action 0 steps back, 1 forward): one always forward, one back."""
    n = RING_STATES
    ring = make_mdp(
        client,
        auth,
        name="ring",
        n_states=n,
        transitions={"kind": "deterministic", "next_state": [[(s - 1) % n, (s + 1) % n] for s in range(n)]},
        layout=None,
    )
    demonstrator_id = make_demonstrator(client, auth)["id"]
    task_ids = []
    for action, states in ((1, list(range(n))), (0, list(range(n - 1, -1, -1)))):
        task_id = make_task(client, auth, demonstrator_id=demonstrator_id, mdp_id=ring["id"])["id"]
        add_demonstrations(client, auth, task_id, [{"states": states, "actions": [action] * (n - 1)}])
        task_ids.append(task_id)
    return demonstrator_id, task_ids


def submit(
    client: TestClient, auth: dict[str, str], demonstrator_id: str, config: dict[str, Any]
) -> dict[str, Any]:
    """POST a job (must be accepted) and return its body."""
    response = client.post(
        "/v1/jobs", json={"demonstrator_id": demonstrator_id, "config": config}, headers=auth
    )
    job = created(response, 202)
    assert response.headers["location"] == f"/v1/jobs/{job['id']}"
    return job


def unsent_job(make_session: sessionmaker[Session], demonstrator_id: str, config: dict[str, Any]) -> str:
    """A job committed as the API does but whose message was never sent (the API died in between): its id."""
    with make_session() as session:
        lab_id = session.get_one(Demonstrator, demonstrator_id).lab_id
        body = {"demonstrator_id": demonstrator_id, "config": config}
        job_id = create_job(session, lab_id=lab_id, body=body, settings=Settings(job_max_attempts=3)).id
        session.commit()
        return job_id


def wait_for(
    client: TestClient,
    auth: dict[str, str],
    job_id: str,
    done: Callable[[dict[str, Any]], bool] = lambda job: job["status"] in TERMINAL,
    *,
    timeout: float = 60.0,
) -> dict[str, Any]:
    """Poll the job until ``done(job)``; fail with its last state after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        job = created(client.get(f"/v1/jobs/{job_id}", headers=auth), 200)
        if done(job):
            return job
        assert time.monotonic() < deadline, f"job did not get there in {timeout} s: {job}"
        time.sleep(0.2)


def all_events(client: TestClient, auth: dict[str, str], job_id: str) -> list[dict[str, Any]]:
    """The job's whole event log, following ``next_cursor`` page by page."""
    events: list[dict[str, Any]] = []
    params: dict[str, Any] = {"limit": 100}
    while True:
        page = created(client.get(f"/v1/jobs/{job_id}/events", params=params, headers=auth), 200)
        events += page["data"]
        if not page["has_more"]:
            return events
        params["cursor"] = page["next_cursor"]
