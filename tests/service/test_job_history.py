"""`GET /v1/jobs/{id}/history`: a job's loss curve from its progress events, latest attempt only, by step."""

from __future__ import annotations

from fastapi import FastAPI
from fastapi.testclient import TestClient

from service.store import jobs
from service.store.models.base import utcnow
from service.store.models.jobs import Job, JobEvent
from tests.service.test_events_stream import finished_job


def sample(job_id: str, attempt: int, step: int) -> JobEvent:
    """A progress event at ``step`` whose losses fall with the step."""
    return JobEvent(
        job_id=job_id,
        at=utcnow(),
        kind="progress",
        attempt=attempt,
        step=step,
        max_steps=20,
        loss=1.0 / step,
        irl_loss=0.9 / step,
        sharing_loss=0.1 / step,
        elapsed_s=0.1 * step,
    )


def test_history_lists_the_progress_samples_by_step_with_every_loss(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    response = client.get(f"/v1/jobs/{job_id}/history", headers=auth)
    assert response.status_code == 200, response.text
    history = response.json()
    assert history["job_id"] == job_id and history["attempt"] == 1 and history["max_steps"] == 20
    assert [p["step"] for p in history["points"]] == [10, 20]
    assert history["points"][0] == {
        "step": 10,
        "loss": 0.1,
        "irl_loss": 0.1,
        "sharing_loss": 0.0,
        "heldout_nll": None,
        "elapsed_s": 1.0,
    }


def test_history_shows_only_the_latest_attempt(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    with app.state.sessionmaker() as session:
        session.get_one(Job, job_id).attempts = 2
        session.add_all([sample(job_id, 2, 5), sample(job_id, 2, 3)])
        session.commit()
    history = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()
    assert history["attempt"] == 2
    assert [p["step"] for p in history["points"]] == [3, 5]


def test_a_long_history_is_thinned_keeping_its_first_and_last_sample(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    extra = jobs.HISTORY_MAX_POINTS + 500
    with app.state.sessionmaker() as session:
        session.add_all([sample(job_id, 1, 20 + i) for i in range(1, extra + 1)])
        session.commit()
    points = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()["points"]
    assert len(points) == jobs.HISTORY_MAX_POINTS
    assert points[0]["step"] == 10 and points[-1]["step"] == 20 + extra


def test_another_labs_job_history_is_not_found(
    app: FastAPI, client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    response = client.get(f"/v1/jobs/{job_id}/history", headers=auth_b)
    assert response.status_code == 404
    assert response.headers["content-type"].startswith("application/problem+json")
