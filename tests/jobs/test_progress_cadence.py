"""A running attempt's progress reaches its event log at least twice a second with the default settings (also
when each database write is slow), so the event stream and the dashboard's live loss curve get two points
a second between the first and the last step."""

from __future__ import annotations

import time

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import select

from metairl_engine.results import Progress
from service.settings import Settings
from service.store.models.jobs import JobEvent
from tests.jobs.test_recovery import running_job
from worker.monitor import Monitor, beat_grid


class SlowWrites(Monitor):
    """A monitor whose every beat takes ``WRITE_S`` longer, as on a busy database."""

    WRITE_S = 0.2

    def beat(self, *, final: bool = False) -> None:
        """Wait, then beat."""
        time.sleep(self.WRITE_S)
        super().beat(final=final)


def default_timing(settings: Settings) -> Settings:
    """The test's settings with the production heartbeat and event interval."""
    defaults = Settings()
    return settings.model_copy(
        update={
            "job_heartbeat_s": defaults.job_heartbeat_s,
            "job_event_interval_s": defaults.job_event_interval_s,
        }
    )


def run_fit(monitor: Monitor, seconds: float) -> int:
    """Report a step every 10 ms to the started ``monitor`` for ``seconds``, as a fit does; the last step."""
    start = time.monotonic()
    step = 0
    while time.monotonic() - start < seconds:
        step += 1
        monitor.report(Progress(step, 10_000, 1.0 / step, 1.0 / step, 0.0, None, time.monotonic() - start))
        time.sleep(0.01)
    return step


def progress_steps(app: FastAPI, job_id: str) -> list[int]:
    """The steps of the job's progress events, oldest first."""
    with app.state.sessionmaker() as session:
        return list(
            session.execute(
                select(JobEvent.step)
                .where(JobEvent.job_id == job_id, JobEvent.kind == "progress")
                .order_by(JobEvent.id)
            ).scalars()
        )


def monitored_fit(
    kind: type[Monitor],
    app: FastAPI,
    client: TestClient,
    auth: dict[str, str],
    settings: Settings,
    *,
    seconds: float,
) -> tuple[int, list[int]]:
    """A fit of ``seconds`` on a running job watched by a ``kind`` monitor with the default timing: its last
    step and the steps of the progress events it left, oldest first."""
    job_id = running_job(app, client, auth, stale=False)
    monitor = kind(app.state.sessionmaker, job_id, 1, default_timing(settings))
    monitor.start()
    step = run_fit(monitor, seconds)
    monitor.close()
    return step, progress_steps(app, job_id)


def test_the_monitor_appends_a_progress_event_twice_a_second_by_default(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    step, steps = monitored_fit(Monitor, app, client, auth, settings, seconds=3.0)
    assert len(steps) >= 5, steps  # 3 s at two a second, less a loaded machine's slack
    assert steps == sorted(steps) and steps[-1] == step


def test_slow_writes_do_not_slow_the_progress_events_below_two_a_second(
    app: FastAPI, client: TestClient, auth: dict[str, str], settings: Settings
) -> None:
    _, steps = monitored_fit(SlowWrites, app, client, auth, settings, seconds=4.0)
    while_running = steps[:-1]  # the last one is written by close()
    # On a grid the beats come every 0.5 s however long each takes; waiting 0.5 s after each 0.2 s write
    # would give one every 0.7 s (5 in 4 s).
    assert len(while_running) >= 7, while_running


@pytest.mark.parametrize(
    ("heartbeat_s", "interval_s", "grid"),
    [
        (1.0, 0.5, (0.5, 1)),
        (0.3, 0.5, (0.25, 2)),
        (1.0, 2.0, (1.0, 2)),
        (30.0, 0.5, (0.5, 1)),
        (0.2, 0.6, (0.2, 3)),
    ],
)
def test_the_beats_divide_the_event_interval_and_come_at_least_every_heartbeat(
    heartbeat_s: float, interval_s: float, grid: tuple[float, int]
) -> None:
    period, beats = beat_grid(heartbeat_s, interval_s)
    assert (round(period, 9), beats) == grid
    assert period <= min(heartbeat_s, 1.0) and abs(period * beats - interval_s) < 1e-9
