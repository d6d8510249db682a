"""`GET /v1/jobs/{id}/history`: a job's loss curve, every stored step once it has succeeded, else its progress
events (latest attempt only), by step."""

from __future__ import annotations

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_engine.results import Progress
from service.domain.jobs import JobHistory
from service.jobs.transitions import claim, transition
from service.store import jobs
from service.store.histories import add_step_history
from service.store.models.base import utcnow
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent
from tests.service.helpers import queued_job
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
    assert history["source"] == "samples"  # it succeeded before every step was kept
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


def engine_steps(n: int, max_steps: int, *, held_out: bool = True) -> list[Progress]:
    """``n`` steps as the engine reports them: losses that are no round decimals, elapsed time growing."""
    return [
        Progress(
            step=step,
            max_steps=max_steps,
            loss=2.0 / (step + 0.37),
            irl_loss=1.7 / (step + 0.37),
            sharing_loss=0.3 / (step + 0.37),
            heldout_nll=1.0 + 1.0 / step if held_out else None,
            elapsed_s=0.013 * step,
        )
        for step in range(1, n + 1)
    ]


def keep_steps(app: FastAPI, job_id: str, steps: list[Progress]) -> None:
    """Store ``steps`` as the job's step history, as the worker does with its results."""
    with app.state.sessionmaker() as session:
        add_step_history(session, job_id, session.get_one(Job, job_id).attempts, steps)
        session.commit()


def test_a_succeeded_job_with_its_steps_kept_returns_every_step_exactly(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)  # its progress samples: steps 10 and 20
    steps = engine_steps(jobs.HISTORY_MAX_POINTS + 1000, 5000)
    keep_steps(app, job_id, steps)
    response = client.get(f"/v1/jobs/{job_id}/history", headers=auth)
    assert response.status_code == 200 and response.headers["content-type"] == "application/json"
    history = response.json()
    JobHistory.model_validate(history)  # the documented body
    assert (history["source"], history["attempt"], history["max_steps"]) == ("steps", 1, 5000)
    assert len(history["points"]) == len(steps)  # every step, never thinned
    for point, step in zip(history["points"], steps, strict=True):
        assert point == {
            "step": step.step,
            "loss": step.loss,
            "irl_loss": step.irl_loss,
            "sharing_loss": step.sharing_loss,
            "heldout_nll": step.heldout_nll,
            "elapsed_s": step.elapsed_s,
        }


def test_steps_without_a_held_out_nll_have_it_null(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    keep_steps(app, job_id, engine_steps(3, 3, held_out=False))
    points = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()["points"]
    assert [p["heldout_nll"] for p in points] == [None, None, None]
    assert [p["step"] for p in points] == [1, 2, 3]


def test_the_steps_of_an_earlier_attempt_are_not_the_latest_curve(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    job_id = finished_job(app, client, auth)
    keep_steps(app, job_id, engine_steps(30, 30))
    with app.state.sessionmaker() as session:
        session.get_one(Job, job_id).attempts = 2
        session.add(sample(job_id, 2, 5))
        session.commit()
    history = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()
    assert (history["source"], history["attempt"]) == ("samples", 2)
    assert [p["step"] for p in history["points"]] == [5]


@pytest.mark.parametrize("status", [JobStatus.CANCELLED, JobStatus.FAILED])
def test_a_cancelled_or_failed_job_keeps_the_progress_samples_it_had(
    app: FastAPI, client: TestClient, auth: dict[str, str], status: JobStatus
) -> None:
    job_id = queued_job(client, auth)
    with app.state.sessionmaker() as session:
        attempt = claim(session, job_id)
        assert attempt is not None
        session.add_all([sample(job_id, attempt, 4), sample(job_id, attempt, 8)])
        transition(session, job_id, JobStatus.RUNNING, status, message="stopped at step 8")
        session.commit()
    history = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()
    assert (history["source"], history["attempt"]) == ("samples", 1)
    assert [p["step"] for p in history["points"]] == [4, 8]


def test_the_longest_history_is_served_whole(app: FastAPI, client: TestClient, auth: dict[str, str]) -> None:
    job_id = finished_job(app, client, auth)
    steps = engine_steps(100_000, 100_000)
    keep_steps(app, job_id, steps)
    points = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()["points"]
    assert len(points) == 100_000 and points[-1]["loss"] == steps[-1].loss


def test_a_job_whose_losses_were_not_finite_reads_lists_and_cancels_with_null_losses(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    """A NaN loss is stored as null (the worker's JSON has no NaN): every read of the job still answers."""
    job_id = queued_job(client, auth)
    with app.state.sessionmaker() as session:
        claim(session, job_id)
        job = session.get_one(Job, job_id)
        job.step, job.max_steps, job.elapsed_s = 3, 20, 0.3
        job.loss = job.irl_loss = job.sharing_loss = None
        event = sample(job_id, 1, 3)
        event.loss = event.irl_loss = event.sharing_loss = None
        session.add(event)
        session.commit()
    read = client.get(f"/v1/jobs/{job_id}", headers=auth)
    assert read.status_code == 200, read.text
    assert read.json()["progress"]["loss"] is None and read.json()["progress"]["step"] == 3
    assert client.get("/v1/jobs", headers=auth).status_code == 200
    history = client.get(f"/v1/jobs/{job_id}/history", headers=auth)
    assert history.status_code == 200 and history.json()["points"][0]["loss"] is None
    assert client.post(f"/v1/jobs/{job_id}/cancel", headers=auth).status_code == 202
