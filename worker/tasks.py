"""The one Celery task: ``metairl.run_job(job_id)``, sent by name by the API and the reaper."""

from __future__ import annotations

import logging

from service.jobs.broker import TASK_NAME
from service.jobs.transitions import claim
from service.settings import get_settings
from worker.celery_app import app
from worker.context import sessions
from worker.monitor import Monitor

log = logging.getLogger(__name__)


@app.task(name=TASK_NAME, acks_late=True, reject_on_worker_lost=True)
def run_job(job_id: str) -> None:
    """Claim the job if it is still queued (the row, not the message, decides) and run that attempt."""
    with sessions()() as session:
        attempt = claim(session, job_id)
        session.commit()
    if attempt is None:
        log.info("job %s is not queued (cancelled, finished or taken by another worker): skipped", job_id)
        return
    log.info("job %s: attempt %d started", job_id, attempt)
    monitor = Monitor(sessions(), job_id, attempt, get_settings())
    monitor.start()  # beating before the (slow) engine import, so the reaper never takes a starting job
    try:
        # Imported only now, so torch loads in the pool process that runs a job, never in the forking parent.
        from worker.runner import run_attempt

        run_attempt(job_id, attempt, monitor)
    finally:
        monitor.close()
