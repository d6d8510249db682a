"""Request-scoped dependencies shared by the routes: the session, the settings, the job queue, a lab's job.

Routes share these (and `service.api.responses`) instead of importing one another.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from service.api.auth import LabDep
from service.api.session import SessionDep
from service.jobs.queue import JobQueue
from service.settings import Settings
from service.store.jobs import get_job
from service.store.models.jobs import Job


def get_app_settings(request: Request) -> Settings:
    """The settings the app was created with."""
    settings: Settings = request.app.state.settings
    return settings


def job_queue(request: Request) -> JobQueue:
    """The queue jobs are sent to (set on the app by `create_app`)."""
    queue: JobQueue = request.app.state.job_queue
    return queue


def lab_job(session: SessionDep, lab: LabDep, job_id: str) -> Job:
    """The lab's job ``job_id``; 404 if it does not exist or belongs to another lab."""
    return get_job(session, job_id, lab_id=lab.id)


__all__ = ["JobDep", "LabDep", "QueueDep", "SessionDep", "SettingsDep"]

SettingsDep = Annotated[Settings, Depends(get_app_settings)]
QueueDep = Annotated[JobQueue, Depends(job_queue)]
JobDep = Annotated[Job, Depends(lab_job)]
