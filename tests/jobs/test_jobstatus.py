"""The job lifecycle table: exactly the transitions of docs/api.md, "Jobs" (plus the reaper's and the broker's edges)."""

from __future__ import annotations

import pytest

from service.store.models.job_status import IllegalTransition, JobStatus

Q, R, S, F, C = (
    JobStatus.QUEUED,
    JobStatus.RUNNING,
    JobStatus.SUCCEEDED,
    JobStatus.FAILED,
    JobStatus.CANCELLED,
)
ALLOWED = {(Q, R), (Q, C), (Q, F), (R, S), (R, F), (R, C), (R, Q)}
"""queued → running | cancelled | failed (broker refused the message); running → succeeded | failed |
cancelled | queued (re-queued by the reaper). Nothing leaves a finished job."""


@pytest.mark.parametrize("old", list(JobStatus))
@pytest.mark.parametrize("new", list(JobStatus))
def test_transition_is_allowed_exactly_when_listed(old: JobStatus, new: JobStatus) -> None:
    assert old.can_become(new) == ((old, new) in ALLOWED)
    if (old, new) in ALLOWED:
        old.check(new)
    else:
        with pytest.raises(IllegalTransition, match=f"{old.value} job cannot become {new.value}"):
            old.check(new)


def test_status_values_are_the_contract_and_finished_ones_are_terminal() -> None:
    assert [s.value for s in JobStatus] == ["queued", "running", "succeeded", "failed", "cancelled"]
    assert {s for s in JobStatus if s.is_terminal} == {S, F, C}
