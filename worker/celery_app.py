"""The worker's Celery app: late acks, one message at a time, time limits and the reaper in every worker.

Start it with ``metairl worker`` or ``python -m celery -A worker.celery_app worker``. A message is
acknowledged only after its job finished (``acks_late``) and is given back if the pool process dies
(``reject_on_worker_lost``); because neither saves a job when the whole worker is killed (the embedded
broker loses the in-flight message, Redis redelivers only after its visibility timeout), each worker
also runs the reaper, which re-queues or fails running jobs whose heartbeat stopped. Before its pool starts, a
worker waits until the database is migrated (`worker.startup`).
"""

from __future__ import annotations

import logging
from typing import Any, ClassVar

from celery import Celery, bootsteps
from celery.signals import worker_init

from service.jobs.broker import celery_config
from service.settings import get_settings

log = logging.getLogger(__name__)


class ReaperStep(bootsteps.StartStopStep):
    """Runs `worker.reaper.reap_once` at start and then every ``reaper_interval_s`` on the worker's timer."""

    requires: ClassVar[set[str]] = {"celery.worker.components:Timer"}

    def __init__(self, parent: Any, **kwargs: Any):
        super().__init__(parent, **kwargs)
        self.tref: Any = None

    def start(self, parent: Any) -> None:
        """Reap once now (jobs orphaned while no worker ran), then periodically."""
        self._reap()
        self.tref = parent.timer.call_repeatedly(get_settings().reaper_interval_s, self._reap)

    def stop(self, parent: Any) -> None:
        """Cancel the periodic call."""
        if self.tref is not None:
            parent.timer.cancel(self.tref)
            self.tref = None

    def _reap(self) -> None:
        """One reaper pass; a failure is logged and retried at the next interval, never fatal."""
        from worker.reaper import reap_once

        try:
            reap_once()
        except Exception:
            log.exception("reaper pass failed; retrying in %s s", get_settings().reaper_interval_s)


class WebhookStep(bootsteps.StartStopStep):
    """Runs `worker.webhooks.Deliverer`, the thread sending webhook deliveries, in the worker's main process."""

    def __init__(self, parent: Any, **kwargs: Any):
        super().__init__(parent, **kwargs)
        self.thread: Any = None

    def start(self, parent: Any) -> None:
        """Start the sending thread."""
        from worker.context import sessions
        from worker.webhooks import Deliverer

        self.thread = Deliverer(sessions(), get_settings())
        self.thread.start()

    def stop(self, parent: Any) -> None:
        """Stop it after its current pass."""
        if self.thread is not None:
            self.thread.stop()
            self.thread = None


def wait_for_migrations(**_: Any) -> None:
    """On ``worker_init``, before the pool, the reaper or the consumer start: wait until the database is
    migrated, so a worker started before the API neither fails every query nor creates an empty database."""
    from worker.startup import wait_until_migrated

    wait_until_migrated(get_settings())


def make_app() -> Celery:
    """The Celery app configured from `Settings` (broker shared with the API via `service.jobs.broker`)."""
    settings = get_settings()
    app = Celery("metairl", include=["worker.tasks"])
    app.conf.update(celery_config(settings))
    app.conf.update(
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        worker_prefetch_multiplier=1,
        worker_concurrency=settings.worker_concurrency,
        task_soft_time_limit=settings.job_time_limit_s,
        task_time_limit=settings.job_time_limit_s + 60,
        worker_send_task_events=False,
        # The embedded broker is one folder: no broadcast control needed, and none wanted polling it.
        worker_enable_remote_control=not app.conf.broker_url.startswith("filesystem://"),
    )
    app.steps["worker"].add(ReaperStep)
    app.steps["worker"].add(WebhookStep)
    worker_init.connect(wait_for_migrations, weak=False)  # once however many apps: one receiver per function
    return app


app = make_app()
