"""``metairl worker``: one Celery worker process (pool of ``concurrency`` job processes) on the configured stores."""

from __future__ import annotations

import os


def prepare_environment(*, concurrency: int) -> None:
    """Set what the job processes read from the environment, before anything loads torch.

    The concurrency goes to the settings, so torch threads are split by it. OpenMP threads wait passively
    (unless ``OMP_WAIT_POLICY`` is set): by default each of torch's threads spins at every barrier, so when
    anything else runs on the cores (the API, another worker, the database) a spinning thread holds a core
    its sibling needs; one other busy process made an 80,000-state step 4× slower (benchmarks/RESULTS.md,
    "Waiting threads").
    """
    os.environ["METAIRL_WORKER_CONCURRENCY"] = str(concurrency)
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def run_worker(*, concurrency: int) -> int:
    """Run a worker until it is stopped (SIGTERM: finish the running jobs; SIGQUIT: now); the exit code."""
    prepare_environment(concurrency=concurrency)
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
