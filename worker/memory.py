"""The memory budget of a job: its fit's estimated peak against what this worker allows, before the fit starts.

A fit too large for the machine would be killed by the kernel part-way, and the reaper would re-run it to
the same end (`METAIRL_JOB_MAX_ATTEMPTS` times). Estimated from the inputs' sizes beforehand
(`metairl_engine.memory.fit_memory`), such a job fails at once with a sentence, and a failure is final.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path

from sqlalchemy.orm import Session

from metairl_engine.config import FitConfig
from metairl_engine.memory import FitMemory, fit_memory
from service.settings import Settings
from service.store.loaders import input_sizes

log = logging.getLogger(__name__)

MIB = 1024 * 1024

AVAILABLE_FRACTION = 0.8
"""Without ``METAIRL_WORKER_MAX_MEMORY_MB``, the share of the memory available when a job starts that its fit may
use (the rest covers the estimate's error and the rest of the machine)."""

CGROUP_FILES = (
    (Path("/sys/fs/cgroup/memory.max"), Path("/sys/fs/cgroup/memory.current")),  # cgroup v2
    (
        Path("/sys/fs/cgroup/memory/memory.limit_in_bytes"),
        Path("/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ),  # cgroup v1
)
"""(limit, usage) of this container's memory cgroup, as a container sees its own."""


class OverBudget(Exception):
    """A job whose fit needs more memory than this worker allows: a sentence saying both and what to change."""

    def __init__(self, needed: FitMemory, limit: int, source: str):
        super().__init__(
            f"The job needs an estimated {needed.total / MIB:,.0f} MiB of memory, more than the "
            f"{limit / MIB:,.0f} MiB this worker allows ({source}); {needed.advice()}, "
            "or run it on a worker with more memory."
        )


def check_memory(
    session: Session, job_id: str, task_ids: Sequence[str], config: FitConfig, settings: Settings
) -> None:
    """Raise `OverBudget` if job ``job_id``'s fit (its tasks, its config) is estimated to need more than
    `memory_limit`."""
    needed = fit_memory(config, **vars(input_sizes(session, task_ids)))
    limit, source = memory_limit(settings)
    log.info("job %s: needs about %.0f MiB, may use %.0f MiB", job_id, needed.total / MIB, limit / MIB)
    if needed.total > limit:
        raise OverBudget(needed, limit, source)


def memory_limit(settings: Settings) -> tuple[int, str]:
    """The bytes one job may use and where that number comes from.

    ``METAIRL_WORKER_MAX_MEMORY_MB`` is the worker's, shared by the jobs it runs at once; unset, a job may use
    `AVAILABLE_FRACTION` of the memory available now (jobs already running hold theirs).
    """
    if settings.worker_max_memory_mb is not None:
        share = "" if settings.worker_concurrency == 1 else f" shared by {settings.worker_concurrency} jobs"
        return (
            settings.worker_max_memory_mb * MIB // settings.worker_concurrency,
            f"METAIRL_WORKER_MAX_MEMORY_MB{share}",
        )
    return (
        int(AVAILABLE_FRACTION * available_memory()),
        f"{AVAILABLE_FRACTION:.0%} of the memory available when the job started; "
        "METAIRL_WORKER_MAX_MEMORY_MB sets it",
    )


def available_memory() -> int:
    """Bytes this process could still allocate: the machine's available memory, or less if its cgroup is limited."""
    available = _meminfo_available()
    for limit_file, usage_file in CGROUP_FILES:
        try:
            limit_text = limit_file.read_text().strip()
            usage = int(usage_file.read_text())
        except (OSError, ValueError):
            continue
        if limit_text.isdigit():  # v2 writes "max" when unlimited (v1 a huge number)
            available = min(available, max(0, int(limit_text) - usage))
    return available


def _meminfo_available() -> int:
    """``MemAvailable`` of /proc/meminfo in bytes (free memory plus what the kernel can reclaim), or the free
    memory where the kernel does not report it."""
    with open("/proc/meminfo") as meminfo:
        for line in meminfo:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
