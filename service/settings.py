"""Process settings from the environment (prefix ``METAIRL_``), shared by the API, the worker and the CLI."""

from __future__ import annotations

import difflib
import logging
import os
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

MIB = 1024 * 1024

WorkerDevice = Literal["auto", "cpu", "cuda"]
"""Values of ``METAIRL_WORKER_DEVICE`` (`worker.runner.fit_device` turns one into a torch device)."""


class Settings(BaseSettings):
    """Where data lives and how big requests may be; every field is ``METAIRL_<NAME>`` in the environment."""

    model_config = SettingsConfigDict(env_prefix="METAIRL_", extra="ignore")

    data_dir: Path = Path("./var")
    """Folder of the SQLite file, the embedded broker's folders and anything else stored on disk."""

    database_url: str | None = None
    """SQLAlchemy URL; None means the SQLite file ``<data_dir>/metairl.db``."""

    broker_url: str | None = None
    """Celery broker URL; None means the embedded filesystem broker under ``data_dir``."""

    max_upload_bytes: int = 256 * MIB
    """Largest multipart request body (``.npz`` / ``.csv`` uploads)."""

    max_json_bytes: int = 64 * MIB
    """Largest JSON request body."""

    max_state_actions: int = 32_000_000
    """Largest MDP, as states × actions (the paper's 100×100 velocity grid: 80,000 × 8 = 640,000); checked on
    upload and again when a job is submitted."""

    max_features: int = 4096
    """Widest feature matrix (features per state); checked on upload and when a job is submitted."""

    max_array_elements: int = 64_000_000
    """Most elements of any one array of an upload (256 MB as float32); an `.npz` member's header is checked
    against this before the member is read."""

    api_max_request_memory_mb: int = Field(default=512, ge=16)
    """Memory one API request may ask for beyond the process's baseline (MiB): every upload's size in memory is
    estimated before it is built (an `.npz` member's declared shape × item size, a CSV's rows, a JSON body, a
    grid's arrays) and a request over it is refused with a 422 naming this setting."""

    max_hidden_units: int = 4096
    """Largest hidden layer a job's ``config.hidden`` may ask for."""

    idempotency_ttl_s: int = 24 * 3600
    """How long an ``Idempotency-Key`` replays its first response."""

    idempotency_lease_s: float = 60.0
    """How long a claimed ``Idempotency-Key`` stays claimed without its request renewing it (every third of
    this while it runs); a retry with the key after the lease lapsed (the API died, or the database dropped
    before the response was recorded) runs the request again instead of answering 409."""

    rate_limit_per_key: float = 200.0
    """Requests a second one API key may make to `/v1`, sustained (0: no limit); over it, 429 with ``Retry-After``.
    Counted in each API process: with N processes a key gets up to N times this."""

    rate_limit_per_key_burst: int = 400
    """Requests one API key may make at once: the limit is this many in a sliding window of burst / rate seconds."""

    rate_limit_per_ip: float = 10.0
    """Failed authentications (401) a second one client address may cause, sustained (0: no limit); while it is
    over, every `/v1` request from the address gets 429 with ``Retry-After``, so a key guesser is slowed down."""

    rate_limit_per_ip_burst: int = 20
    """Failed authentications one client address may cause at once (this many in burst / rate seconds)."""

    api_key_cache_s: float = 0.0
    """How long an API process trusts a key the database confirmed; a revoked key is refused within this (0: always ask)."""

    db_pool_size: int = 20
    """PostgreSQL connections each process keeps open per pool (an API process serves up to 40 requests at once
    from its thread pool, and has a second, async pool of this size for its hot reads: `service.api.async_db`)."""

    db_max_overflow: int = 20
    """Extra PostgreSQL connections a process may open beyond each pool at a peak (closed when returned)."""

    db_pool_timeout_s: float = Field(default=10.0, gt=0)
    """How long a request waits for a pooled PostgreSQL connection before it is answered 503 with
    ``Retry-After`` (every connection busy)."""

    db_pool_recycle_s: int = 1800
    """A pooled PostgreSQL connection older than this (seconds) is replaced before use, never pinged per request."""

    # Jobs and workers (docs/api.md, "Jobs"): heartbeats, the reaper, attempts and time limits.
    queue_name: str = "metairl"
    """The broker queue jobs travel on (deployments sharing one broker give each its own)."""

    worker_concurrency: int = 1
    """Jobs one worker process runs at once; torch threads per job = cores owned / this."""

    worker_threads: int = Field(default=0, ge=0)
    """Torch threads per job; 0: the cores the worker may use (its CPU affinity, capped by a container's CPU
    quota) divided by ``worker_concurrency``. Set it when several workers share one machine's cores."""

    worker_device: WorkerDevice = "auto"
    """Where a worker runs its meta-IRL fits: ``auto`` a CUDA GPU when torch sees one, else the CPU; ``cuda``
    fails each job with a message saying so when torch sees none (MaxEnt fits always run on the CPU)."""

    worker_max_memory_mb: int | None = None
    """Memory (MiB) a worker's jobs may use, shared by those it runs at once: a job whose fit is estimated to
    need more fails at once. None: 80 % of the memory available when the job starts."""

    job_heartbeat_s: float = 1.0
    """How often a running job writes its heartbeat and progress and reads its cancel flag (≤ 1 s)."""

    job_stale_after_s: float = 60.0
    """A running job whose heartbeat is older than this is presumed dead and handed to the reaper."""

    reaper_interval_s: float = 15.0
    """How often each worker looks for running jobs whose heartbeat stopped and queued jobs whose message was lost."""

    job_requeue_after_s: float = 30.0
    """A queued job no worker claimed for this long, while the broker queue is empty, has its message sent again
    (a worker claims a job the moment it takes its message, and a duplicate message is skipped, so 30 s is safe)."""

    job_max_resends: int = 3
    """Times the reaper sends a queued job's message again before failing the job (its messages keep getting lost)."""

    job_event_interval_s: float = 0.5
    """Least time between two progress events appended to a job's log (its loss curve: two points a second)."""

    job_max_attempts: int = 3
    """Attempts a job gets (the first run plus re-runs after a worker died) before it is failed."""

    job_time_limit_s: int = 6 * 3600
    """Longest a job may run before it is failed (the broker's visibility timeout is set above this)."""

    # Live events and webhooks (docs/api.md, "Following a job live" and "Webhooks").
    events_poll_s: float = 0.5
    """How often an open event stream (`GET /v1/jobs/{id}/events`, `text/event-stream`) looks for new events."""

    events_stream_max_s: float = 3600.0
    """Longest one event stream stays open; the client reconnects with ``Last-Event-ID`` and goes on."""

    events_max_streams_per_key: int = Field(default=64, ge=1)
    """Event streams (`GET /v1/jobs/{id}/events` as SSE) one API key may hold open at once in one API process;
    one more is a 429 with ``Retry-After``. A stream holds no database connection between its polls."""

    webhook_allow_private: bool = False
    """Accept webhook URLs on private, loopback or link-local addresses (tests, one-machine set-ups)."""

    webhook_poll_s: float = 1.0
    """How often each worker looks for webhook deliveries that are due."""

    webhook_timeout_s: float = 5.0
    """How long one webhook delivery attempt waits for the receiver."""

    webhook_max_attempts: int = 8
    """Delivery attempts of one webhook event before it is given up (retried with exponential backoff)."""

    webhook_backoff_s: float = 5.0
    """Wait before the second delivery attempt; each later wait doubles (capped at an hour)."""

    webhook_max_per_lab: int = Field(default=25, ge=1)
    """Most webhooks one lab may have; creating one more is a 409."""

    webhook_concurrency: int = Field(default=8, ge=1)
    """Deliveries one worker process sends at once (threads)."""

    webhook_lab_concurrency: int = Field(default=2, ge=1)
    """Of those, the most that one lab's deliveries may take: a lab with slow receivers leaves the other
    slots to other labs."""

    webhook_target_concurrency: int = Field(default=2, ge=1)
    """Deliveries sent at once to one target (host and port)."""

    @property
    def resolved_database_url(self) -> str:
        """The database URL to connect to: the configured one, or the absolute SQLite file in data_dir."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'metairl.db').resolve()}"


LAB_TOOL_VARIABLES = frozenset({"METAIRL_API_KEY", "METAIRL_URL"})
"""``METAIRL_`` variables the lab tools read (the client, ``metairl demo``), not settings of the service."""


def unknown_variables(environ: Mapping[str, str]) -> list[str]:
    """One line per ``METAIRL_`` variable of ``environ`` that names no setting (a misspelt one is otherwise
    ignored, and its setting keeps its default), with the closest setting's name when there is one."""
    known = {f"METAIRL_{name.upper()}" for name in Settings.model_fields}
    lines = []
    for name in sorted(environ):
        if name.startswith("METAIRL_") and name not in known | LAB_TOOL_VARIABLES:
            close = difflib.get_close_matches(name, sorted(known), n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            lines.append(f"{name} is not a metairl setting and is ignored{hint}")
    return lines


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The settings of this process, read from the environment once; each variable that names no setting
    is logged as a warning."""
    for line in unknown_variables(os.environ):
        logging.getLogger("metairl.settings").warning(line)
    return Settings()
