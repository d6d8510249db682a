"""The job-queue seam: how the API (and the reaper) hand a committed job to the workers.

`JobQueue` is the protocol; `CeleryJobQueue` sends the ``metairl.run_job`` task BY NAME, so the API
process imports neither ``worker/`` nor torch. The message carries only the job id: the job row is the
source of truth, and a message for a job that is no longer queued is simply skipped by the worker.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Protocol

from service.jobs.broker import TASK_NAME, celery_config, job_queue
from service.settings import Settings

if TYPE_CHECKING:
    from celery import Celery


class EnqueueFailed(RuntimeError):
    """The broker could not take the message; the text says which broker and why."""


class JobQueue(Protocol):
    """Something that delivers a job id to a worker."""

    def enqueue(self, job_id: str) -> None:
        """Send the job to a worker; raise `EnqueueFailed` if the message could not be sent."""
        ...

    def waiting(self) -> int:
        """Messages in the broker queue not yet delivered to a worker; raise `EnqueueFailed` if unreachable."""
        ...


class CeleryJobQueue:
    """Sends ``metairl.run_job(job_id)`` through Celery to the configured broker.

    The Celery app is built on first use, so an API process that never submits a job never loads Celery's
    sending machinery (the broker settings, and the embedded broker's folders, are made at once).
    """

    def __init__(self, settings: Settings):
        self._config = celery_config(settings)
        self._broker = self._config["broker_url"]
        self._queue = job_queue(settings)
        self._celery: Celery | None = None
        self._lock = threading.Lock()

    @property
    def _app(self) -> Celery:
        """The Celery app that sends (created once, on first use)."""
        if self._celery is None:
            with self._lock:
                if self._celery is None:
                    from celery import Celery

                    app = Celery("metairl-api", set_as_current=False)
                    app.conf.update(self._config)
                    self._celery = app
        return self._celery

    def enqueue(self, job_id: str) -> None:
        """Publish the task, retrying the connection briefly before giving up with `EnqueueFailed`."""
        try:
            self._app.send_task(
                TASK_NAME,
                args=[job_id],
                retry=True,
                retry_policy={
                    "max_retries": 2,
                    "interval_start": 0.2,
                    "interval_step": 0.5,
                    "interval_max": 1,
                },
            )
        except Exception as exc:  # kombu raises many types (OperationalError, OSError, ChannelError…)
            raise EnqueueFailed(f"could not reach the job broker {self._broker!r}: {exc}") from exc

    def waiting(self) -> int:
        """Declare the job queue as the workers do (a no-op if it exists) and return its ready-message count."""
        try:
            with self._app.connection_for_write() as connection:
                _, count, _ = self._queue(connection.default_channel).queue_declare()
        except Exception as exc:  # as in `enqueue`: any transport error means the broker is unreachable
            raise EnqueueFailed(f"could not reach the job broker {self._broker!r}: {exc}") from exc
        return int(count)
