"""``metairl worker``: one Celery worker process (pool of ``concurrency`` job processes) on the configured stores."""

from __future__ import annotations

import os


def run_worker(*, concurrency: int) -> int:
    """Run a worker until it is stopped (SIGTERM: finish the running jobs; SIGQUIT: now); the exit code."""
    # Settings are read from the environment: pass the concurrency on so torch threads are split by it.
    os.environ["METAIRL_WORKER_CONCURRENCY"] = str(concurrency)
    from worker.celery_app import app

    code = app.start(
        argv=[
            "worker",
            f"--concurrency={concurrency}",
            "--loglevel=INFO",
            "--without-mingle",
            "--without-gossip",
        ]
    )
    return int(code or 0)
