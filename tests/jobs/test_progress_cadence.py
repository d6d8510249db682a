"""A running attempt's progress reaches its event log at least twice a second with the default settings, so
the dashboard's loss curve has points between the first and the last step."""

from __future__ import annotations

import time

from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import select

from metairl_engine.results import Progress
from service.settings import Settings
from service.store.models.jobs import JobEvent
from tests.jobs.test_recovery import running_job
from worker.monitor import Monitor


def test_the_monitor_appends_a_progress_event_twice_a_second_by_default(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    defaults = Settings()
    timed = settings.model_copy(
        update={
            "job_heartbeat_s": defaults.job_heartbeat_s,
            "job_event_interval_s": defaults.job_event_interval_s,
        }
    )
    job_id = running_job(app, client, auth, stale=False)
    monitor = Monitor(app.state.sessionmaker, job_id, 1, timed)
    monitor.start()
    start = time.monotonic()
    step = 0
    while time.monotonic() - start < 3.0:  # a fit reporting a step every 10 ms for 3 s
        step += 1
        monitor.report(Progress(step, 10_000, 1.0 / step, 1.0 / step, 0.0, None, time.monotonic() - start))
        time.sleep(0.01)
    monitor.close()
    with app.state.sessionmaker() as session:
        steps = list(
            session.execute(
                select(JobEvent.step).where(JobEvent.job_id == job_id, JobEvent.kind == "progress")
            ).scalars()
        )
    assert len(steps) >= 5, steps  # 3 s at two a second, less a loaded machine's slack
    assert steps == sorted(steps) and steps[-1] == step
