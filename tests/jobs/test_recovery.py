"""Crash recovery without a worker process: the reaper's decisions and attempt fencing, on a real database.

A "crash" here is a job claimed by an attempt whose heartbeat then stops, or a queued job whose message
was never sent; the reaper and the fenced writes are called directly, on SQLite and PostgreSQL, with the
embedded broker as the real queue (time moves on through the reaper's ``now``).
"""

from __future__ import annotations

import threading
from dataclasses import replace
from datetime import timedelta

import numpy as np
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import func, select, update

from metairl_engine.config import FitConfig
from metairl_engine.results import FitResult, Progress
from service.jobs.queue import CeleryJobQueue
from service.jobs.transitions import claim
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, JobEvent, Reward, StepHistory
from tests.jobs.helpers import QUICK, demonstrated_tasks, submit, unsent_job
from worker.monitor import Monitor
from worker.reaper import RESENT, Reaped, reap, resend_lost
from worker.runner import store_results


def running_job(app: FastAPI, client: TestClient, auth: dict[str, str], *, stale: bool = True) -> str:
    """A submitted job claimed by attempt 1, whose heartbeat is a minute old when ``stale``."""
    demonstrator_id, _ = demonstrated_tasks(client, auth)
    job_id = submit(client, auth, demonstrator_id, QUICK)["id"]
    with app.state.sessionmaker() as session:
        assert claim(session, job_id) == 1
        if stale:
            session.execute(
                update(Job).where(Job.id == job_id).values(heartbeat_at=utcnow() - timedelta(minutes=1))
            )
        session.commit()
    return job_id


def job_row(app: FastAPI, job_id: str) -> Job:
    """The job row as stored now."""
    with app.state.sessionmaker() as session:
        return session.get_one(Job, job_id)


def fake_result(n_tasks: int, n_states: int = 3, n_actions: int = 2) -> FitResult:
    """A well-formed result of the right shapes (the fencing under test does not care about values)."""
    rng = np.random.default_rng(0)
    policies = rng.random((n_tasks, n_states, n_actions)).astype(np.float32)
    return FitResult(
        baseline=rng.random(n_states).astype(np.float32),
        rewards=rng.random((n_tasks, n_states)).astype(np.float32),
        values=rng.random((n_tasks, n_states)).astype(np.float32),
        policies=policies / policies.sum(axis=2, keepdims=True),
        history=[
            Progress(step, 4, 1.0 / step, 0.8 / step, 0.2 / step, None, 0.01 * step) for step in range(1, 5)
        ],
        best_step=4,
        config=FitConfig(),
    )


def test_stale_running_job_is_requeued_once_even_with_concurrent_reapers(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    queue = CeleryJobQueue(settings)
    results: list[list[object]] = []
    reapers = [
        threading.Thread(target=lambda: results.append(list(reap(app.state.sessionmaker, settings, queue))))
        for _ in range(4)
    ]
    for thread in reapers:
        thread.start()
    for thread in reapers:
        thread.join()
    acted = [r for batch in results for r in batch if getattr(r, "job_id", None) == job_id]
    assert len(acted) == 1
    row = job_row(app, job_id)
    assert (row.status, row.attempts, row.heartbeat_at) == ("queued", 1, None)
    with app.state.sessionmaker() as session:
        messages = (
            session.execute(
                select(JobEvent.message).where(
                    JobEvent.job_id == job_id, JobEvent.status == "queued", JobEvent.attempt == 1
                )
            )
            .scalars()
            .all()
        )
    assert len(messages) == 1
    assert "stopped sending heartbeats" in messages[0] and "attempt 2 of 3" in messages[0]
    with app.state.sessionmaker() as session:  # the re-queued job can be claimed by the next attempt
        assert claim(session, job_id) == 2


def test_a_new_attempt_shows_no_progress_until_it_reports_its_own(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    with app.state.sessionmaker() as session:  # attempt 1 had reached step 40 when its worker died
        reached = {"step": 40, "max_steps": 100, "loss": 1.5, "irl_loss": 1.4, "sharing_loss": 0.1}
        session.execute(update(Job).where(Job.id == job_id).values(heldout_nll=1.6, elapsed_s=3.0, **reached))
        session.commit()
    assert client.get(f"/v1/jobs/{job_id}", headers=auth).json()["progress"]["step"] == 40
    list(reap(app.state.sessionmaker, settings, CeleryJobQueue(settings)))
    with app.state.sessionmaker() as session:
        assert claim(session, job_id) == 2
        session.commit()
    job = client.get(f"/v1/jobs/{job_id}", headers=auth).json()
    assert (job["status"], job["attempts"], job["progress"]) == ("running", 2, None)


def test_job_with_a_fresh_heartbeat_is_left_alone(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth, stale=False)
    assert reap(app.state.sessionmaker, settings, CeleryJobQueue(settings)) == []
    assert job_row(app, job_id).status == "running"


def test_job_out_of_attempts_fails_with_a_sentence_saying_why(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    with app.state.sessionmaker() as session:
        session.execute(update(Job).where(Job.id == job_id).values(max_attempts=1))
        session.commit()
    [reaped] = reap(app.state.sessionmaker, settings, CeleryJobQueue(settings))
    assert reaped.status is JobStatus.FAILED
    job = client.get(f"/v1/jobs/{job_id}", headers=auth).json()
    assert job["status"] == "failed"
    assert job["error"].startswith("The job was started 1 times and each time its worker stopped responding")
    assert "submit it again" in job["error"]


def test_stale_job_with_cancel_requested_ends_cancelled(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    assert client.post(f"/v1/jobs/{job_id}/cancel", headers=auth).json()["cancel_requested"] is True
    [reaped] = reap(app.state.sessionmaker, settings, CeleryJobQueue(settings))
    assert reaped.status is JobStatus.CANCELLED
    assert job_row(app, job_id).status == "cancelled"


def test_only_the_attempt_that_owns_the_job_can_store_results(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    reap(app.state.sessionmaker, settings, CeleryJobQueue(settings))
    with app.state.sessionmaker() as session:
        assert claim(session, job_id) == 2
        session.commit()
    job = job_row(app, job_id)

    def count() -> tuple[int, int]:
        """The job's reward rows and stored step histories."""
        with app.state.sessionmaker() as session:
            rewards = session.execute(
                select(func.count()).select_from(Reward).where(Reward.job_id == job_id)
            ).scalar_one()
            histories = session.execute(
                select(func.count()).select_from(StepHistory).where(StepHistory.job_id == job_id)
            ).scalar_one()
            return rewards, histories

    zombie = Monitor(app.state.sessionmaker, job_id, 1, settings)
    zombie.beat()
    assert zombie.lost and zombie.should_stop()
    for attempt, expected in (
        (1, (0, 0)),
        (2, (3, 1)),
        (2, (3, 1)),
    ):  # the zombie, the owner, the owner again
        store_results(app.state.sessionmaker, job_id, attempt, result=fake_result(2))
        assert count() == expected
    assert job_row(app, job_id).status == "succeeded"
    rewards = client.get(f"/v1/jobs/{job_id}/rewards", headers=auth).json()
    assert [t["task_id"] for t in rewards["tasks"]] == job.task_ids
    history = client.get(f"/v1/jobs/{job_id}/history", headers=auth).json()
    assert (history["source"], history["attempt"], len(history["points"])) == ("steps", 2, 4)


def test_stored_results_keep_the_shrinkage_and_sparsity_of_a_meta_irl_fit_and_none_of_maxent(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    """Maxent learns no baseline to shrink toward: its λ and q (1 and 0 by the engine's default) are not a
    choice made."""
    for config, expected in ((FitConfig(), (0.25, 0.9)), (FitConfig(method="maxent"), (None, None))):
        job_id = running_job(app, client, auth, stale=False)
        result = replace(fake_result(2), config=config, shrinkage=0.25, sparsity=0.9)
        store_results(app.state.sessionmaker, job_id, 1, result=result)
        job = client.get(f"/v1/jobs/{job_id}", headers=auth).json()
        assert (job["status"], job["shrinkage"], job["sparsity"]) == ("succeeded", *expected)


def test_a_succeeded_job_shows_the_config_as_fitted_with_the_choice_auto_left_to_the_fit(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth)
    job = submit(client, auth, demonstrator_id, {**QUICK, "task_features": "auto"})
    assert job["config"]["task_features"] == "auto"
    with app.state.sessionmaker() as session:
        assert claim(session, job["id"]) == 1
        session.commit()
    fitted = replace(FitConfig.from_dict(job["config"]), task_features="no")
    store_results(app.state.sessionmaker, job["id"], 1, result=replace(fake_result(2), config=fitted))
    shown = client.get(f"/v1/jobs/{job['id']}", headers=auth).json()
    assert shown["status"] == "succeeded" and shown["config"] == fitted.to_dict()


def test_monitor_passes_a_cancel_request_to_the_fit(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth, stale=False)
    monitor = Monitor(app.state.sessionmaker, job_id, 1, settings)
    monitor.beat()
    assert not monitor.should_stop()
    client.post(f"/v1/jobs/{job_id}/cancel", headers=auth)
    monitor.beat()
    assert monitor.should_stop() and not monitor.lost


def test_attempt_killed_by_the_hard_time_limit_fails_at_once_instead_of_rerunning(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    job_id = running_job(app, client, auth)
    with app.state.sessionmaker() as session:  # it kept beating past the limit, then the pool process died
        beat = session.get_one(Job, job_id).heartbeat_at
        assert beat is not None
        session.execute(
            update(Job)
            .where(Job.id == job_id)
            .values(started_at=beat - timedelta(seconds=settings.job_time_limit_s + 60))
        )
        session.commit()
    [reaped] = reap(app.state.sessionmaker, settings, CeleryJobQueue(settings))
    assert reaped.status is JobStatus.FAILED
    job = client.get(f"/v1/jobs/{job_id}", headers=auth).json()
    assert (job["status"], job["attempts"]) == ("failed", 1)
    assert job["error"].startswith(f"The job ran longer than the limit of {settings.job_time_limit_s} s")
    assert "METAIRL_JOB_TIME_LIMIT_S" in job["error"]


def resends(app: FastAPI, job_id: str) -> list[str]:
    """The messages of the job's re-send events."""
    with app.state.sessionmaker() as session:
        return list(
            session.execute(
                select(JobEvent.message).where(JobEvent.job_id == job_id, JobEvent.message.startswith(RESENT))
            ).scalars()
        )


def test_lost_message_is_sent_again_once_even_with_concurrent_reapers(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    job_id = unsent_job(app.state.sessionmaker, demonstrator_id, QUICK)
    # Too soon for this job; older ones of other tests (the database is shared) may be sent again, to a queue
    # of their own, so the reapers below still find theirs empty.
    elsewhere = CeleryJobQueue(settings.model_copy(update={"queue_name": "too-soon"}))
    assert job_id not in {r.job_id for r in resend_lost(app.state.sessionmaker, settings, elsewhere)}
    queue = CeleryJobQueue(settings)
    later = utcnow() + timedelta(seconds=settings.job_requeue_after_s + 1)
    results: list[Reaped] = []
    reapers = [
        threading.Thread(
            target=lambda: results.extend(resend_lost(app.state.sessionmaker, settings, queue, now=later))
        )
        for _ in range(4)
    ]
    for thread in reapers:
        thread.start()
    for thread in reapers:
        thread.join()
    assert [r.status for r in results if r.job_id == job_id] == [JobStatus.QUEUED]  # the database is shared
    [message] = resends(app, job_id)
    assert message.startswith(f"{RESENT} (1 of {settings.job_max_resends}): no worker claimed the job")
    with app.state.sessionmaker() as session:  # the message that does arrive claims it; any other is skipped
        assert claim(session, job_id) == 1
        assert claim(session, job_id) is None


def test_queued_job_behind_a_backlog_is_not_sent_again(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    job_id = submit(client, auth, demonstrator_id, QUICK)["id"]  # its message waits in the broker queue
    later = utcnow() + timedelta(seconds=settings.job_requeue_after_s + 1)
    assert resend_lost(app.state.sessionmaker, settings, CeleryJobQueue(settings), now=later) == []
    assert resends(app, job_id) == [] and job_row(app, job_id).status == "queued"


def test_job_whose_messages_keep_getting_lost_fails_with_a_sentence_after_the_cap(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    demonstrator_id, _ = demonstrated_tasks(client, auth, 1)
    job_id = unsent_job(app.state.sessionmaker, demonstrator_id, QUICK)
    step = timedelta(seconds=settings.job_requeue_after_s + 1)
    for i in range(1, settings.job_max_resends + 2):
        # Each round sends to a queue of its own that nobody reads: the next round finds an empty one again.
        lost = CeleryJobQueue(settings.model_copy(update={"queue_name": f"lost-{i}"}))
        reaped = resend_lost(app.state.sessionmaker, settings, lost, now=utcnow() + i * step)
        assert [r.status for r in reaped if r.job_id == job_id] == [
            JobStatus.QUEUED if i <= settings.job_max_resends else JobStatus.FAILED
        ]
    assert len(resends(app, job_id)) == settings.job_max_resends
    job = client.get(f"/v1/jobs/{job_id}", headers=auth).json()
    assert job["status"] == "failed" and job["attempts"] == 0
    assert job["error"].startswith(f"The job's message was sent {settings.job_max_resends + 1} times")
    assert "submit the job again" in job["error"]
