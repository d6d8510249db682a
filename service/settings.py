"""Process settings from the environment (prefix ``METAIRL_``), shared by the API, the worker and the CLI."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic_settings import BaseSettings, SettingsConfigDict

MIB = 1024 * 1024


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

    idempotency_ttl_s: int = 24 * 3600
    """How long an ``Idempotency-Key`` replays its first response."""

    # Jobs and workers (API.md §5): heartbeats, the reaper, attempts and time limits.
    queue_name: str = "metairl"
    """The broker queue jobs travel on (deployments sharing one broker give each its own)."""

    worker_concurrency: int = 1
    """Jobs one worker process runs at once; torch threads per job = cores owned / this."""

    job_heartbeat_s: float = 1.0
    """How often a running job writes its heartbeat and progress and reads its cancel flag (≤ 1 s)."""

    job_stale_after_s: float = 60.0
    """A running job whose heartbeat is older than this is presumed dead and handed to the reaper."""

    reaper_interval_s: float = 15.0
    """How often each worker looks for running jobs whose heartbeat stopped and queued jobs whose message was lost."""

    job_requeue_after_s: float = 300.0
    """A queued job no worker claimed for this long, while the broker queue is empty, has its message sent again."""

    job_max_resends: int = 3
    """Times the reaper sends a queued job's message again before failing the job (its messages keep getting lost)."""

    job_event_interval_s: float = 5.0
    """Least time between two progress events appended to a job's log."""

    job_max_attempts: int = 3
    """Attempts a job gets (the first run plus re-runs after a worker died) before it is failed."""

    job_time_limit_s: int = 6 * 3600
    """Longest a job may run before it is failed (the broker's visibility timeout is set above this)."""

    @property
    def resolved_database_url(self) -> str:
        """The database URL to connect to: the configured one, or the absolute SQLite file in data_dir."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'metairl.db').resolve()}"


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The settings of this process, read from the environment once."""
    return Settings()
