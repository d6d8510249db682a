"""The job lifecycle (docs/api.md, "Jobs"): the five contract statuses and the only transitions allowed between them.

Every status write in the code base goes through `JobStatus.can_become` (via `service.jobs.transitions.transition`),
so this table is the single definition of the lifecycle.
"""

from __future__ import annotations

from enum import StrEnum


class IllegalTransition(ValueError):
    """A programming error: code tried to move a job along an edge the lifecycle does not have."""


class JobStatus(StrEnum):
    """Where a job is in its life; the string values are the API contract."""

    QUEUED = "queued"
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"

    @property
    def is_terminal(self) -> bool:
        """True once the job can never change again (succeeded, failed or cancelled)."""
        return not _ALLOWED[self]

    def can_become(self, new: JobStatus) -> bool:
        """Whether a job in this status may move to ``new``."""
        return new in _ALLOWED[self]

    def check(self, new: JobStatus) -> None:
        """Raise `IllegalTransition` unless this status may move to ``new``."""
        if not self.can_become(new):
            raise IllegalTransition(f"a {self.value} job cannot become {new.value}")


_ALLOWED: dict[JobStatus, frozenset[JobStatus]] = {
    # queued → failed: the message could not be sent to the broker (the job row is kept, with the reason).
    JobStatus.QUEUED: frozenset({JobStatus.RUNNING, JobStatus.CANCELLED, JobStatus.FAILED}),
    # running → queued: the reaper gives a job whose worker died another attempt.
    JobStatus.RUNNING: frozenset(
        {JobStatus.SUCCEEDED, JobStatus.FAILED, JobStatus.CANCELLED, JobStatus.QUEUED}
    ),
    JobStatus.SUCCEEDED: frozenset(),
    JobStatus.FAILED: frozenset(),
    JobStatus.CANCELLED: frozenset(),
}
