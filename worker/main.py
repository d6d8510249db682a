"""``metairl worker``: one Celery worker process (pool of ``concurrency`` job processes) on the configured stores."""

from __future__ import annotations

import os
import sys
from typing import Any


def prepare_environment(*, concurrency: int | None) -> None:
    """Set what the job processes read from the environment, before anything loads torch.

    The concurrency goes to the settings, so torch threads are split by it. OpenMP threads spin only briefly
    at a barrier before they sleep (``GOMP_SPINCOUNT`` 3000, unless set): by default each of torch's threads
    spins for long, so when anything else runs on the cores (the API, another worker, the database) a
    spinning thread holds a core its sibling needs. With one other busy process an 80,000-state step took
    0.051 s per task-step spinning and 0.027 with the short spin, and 0.011 / 0.012 on quiet cores
    (16 tasks of ``python -m benchmarks.scale``, 12 steps, torch's default 2 threads).
    """
    if concurrency is not None:  # else METAIRL_WORKER_CONCURRENCY (default 1) as the environment sets it
        os.environ["METAIRL_WORKER_CONCURRENCY"] = str(concurrency)
    os.environ.setdefault("GOMP_SPINCOUNT", "3000")


def announce_ready(sender: Any, **_: Any) -> None:
    """Print ``<hostname> ready.`` on the real stdout (Celery redirects ``sys.stdout`` to its log at WARNING)
    once the worker consumes: a quiet worker logs no INFO line saying so, and `metairl serve` waits for one."""
    print(f"{sender.hostname} ready.", file=sys.__stdout__, flush=True)


def run_worker(*, concurrency: int | None = None, quiet: bool = False, name: str | None = None) -> int:
    """Run a worker until it is stopped (SIGTERM: finish the running jobs; SIGQUIT: now); the exit code.
    ``concurrency`` None: the setting's (``METAIRL_WORKER_CONCURRENCY``). ``quiet`` leaves out Celery's
    start-up banner and its INFO lines (Celery's log level WARNING: warnings, errors and failed jobs still
    show) and says ``<hostname> ready.`` alone (`metairl serve` prints its own summary). ``name``: the
    Celery node name (None: Celery's ``celery@HOST``); two workers of one name on RabbitMQ cannot both
    consume the name's control queue, so the second dies at start."""
    prepare_environment(concurrency=concurrency)
    from celery.signals import worker_ready

    from service.settings import Settings
    from worker.celery_app import app

    concurrency = (
        Settings().worker_concurrency
    )  # the environment as prepared (the cached settings may predate it)

    if quiet:
        worker_ready.connect(announce_ready)
    code = app.start(
        argv=[
            *(["--quiet"] if quiet else []),
            "worker",
            f"--concurrency={concurrency}",
            f"--loglevel={'WARNING' if quiet else 'INFO'}",
            "--without-mingle",
            "--without-gossip",
            *([f"--hostname={name}"] if name else []),
        ]
    )
    return int(code or 0)
