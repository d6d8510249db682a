"""A Python client of the metairl HTTP API for lab scripts: numpy arrays in, numpy arrays out.

    from metairl_client import Client, MetairlError

    with Client("http://127.0.0.1:8000", api_key) as lab:
        mdp_id = lab.upload_mdp(name="plate", gamma=0.9, arrays={"next_state": next_state})
        ...
        job = lab.wait(lab.submit_job(demonstrator_id).id)   # a progress bar on stderr
        baseline, per_task = lab.rewards(job.id)              # numpy arrays

It needs only httpx and numpy, and imports nothing else of metairl. Every error answer of the service
raises `MetairlError`, which carries the problem+json (status, title, detail, errors).
"""

from metairl_client._client import (
    TERMINAL_STATUSES,
    Client,
    JobRewardIds,
    JobState,
    MetairlError,
    TrajectoryLike,
    progress_bar,
)

__all__ = [
    "TERMINAL_STATUSES",
    "Client",
    "JobRewardIds",
    "JobState",
    "MetairlError",
    "TrajectoryLike",
    "progress_bar",
]
