"""A Python client of the metairl HTTP API for lab scripts: numpy arrays in, numpy arrays out.

    from metairl_client import Client, MetairlError

    with Client("http://127.0.0.1:8000", api_key) as lab:
        mdp_id = lab.upload_mdp(name="plate", gamma=0.9, arrays={"next_state": next_state})
        ...
        job = lab.wait(lab.submit_job(demonstrator_id).id)   # a progress bar on stderr
        baseline, per_task = lab.rewards(job.id)              # numpy arrays

`AsyncClient` is the same for asyncio. It needs httpx, httpx-sse, numpy and tqdm, and imports nothing else of
metairl. Requests are retried on connection errors, 429 and 503; every error raises a `MetairlError`
subclass carrying the problem+json (docs/client.md).
"""

from metairl_client._async_client import AsyncClient
from metairl_client._client import Client
from metairl_client._errors import (
    APIConnectionError,
    APIStatusError,
    APITimeoutError,
    AuthenticationError,
    BadRequestError,
    ConflictError,
    InternalServerError,
    InvalidRequestError,
    MetairlError,
    NotFoundError,
    PermissionDeniedError,
    RateLimitError,
    RequestTooLargeError,
    ServiceUnavailableError,
    UnprocessableEntityError,
)
from metairl_client._models import (
    TERMINAL_STATUSES,
    JobRewardIds,
    JobState,
    Page,
    TrajectoryLike,
    progress_bar,
)
from metairl_client._transport import Retries
from metairl_client._version import __version__

__all__ = [
    "TERMINAL_STATUSES",
    "APIConnectionError",
    "APIStatusError",
    "APITimeoutError",
    "AsyncClient",
    "AuthenticationError",
    "BadRequestError",
    "Client",
    "ConflictError",
    "InternalServerError",
    "InvalidRequestError",
    "JobRewardIds",
    "JobState",
    "MetairlError",
    "NotFoundError",
    "Page",
    "PermissionDeniedError",
    "RateLimitError",
    "RequestTooLargeError",
    "Retries",
    "ServiceUnavailableError",
    "TrajectoryLike",
    "UnprocessableEntityError",
    "__version__",
    "progress_bar",
]
