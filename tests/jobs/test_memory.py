"""The worker's memory budget without a worker: the limit a job gets and the sentence it fails with."""

from __future__ import annotations

from pathlib import Path

import pytest

from metairl_engine.config import FitConfig
from metairl_engine.memory import fit_memory
from service.settings import Settings
from worker import memory
from worker.memory import MIB, OverBudget, available_memory, memory_limit


def test_the_setting_is_the_workers_memory_shared_by_its_concurrent_jobs() -> None:
    assert memory_limit(Settings(worker_max_memory_mb=2048)) == (2048 * MIB, "METAIRL_WORKER_MAX_MEMORY_MB")
    limit, source = memory_limit(Settings(worker_max_memory_mb=2048, worker_concurrency=4))
    assert limit == 512 * MIB and "shared by 4 jobs" in source


def test_without_the_setting_a_job_may_use_most_of_the_available_memory() -> None:
    limit, source = memory_limit(Settings())
    assert 0 < limit < available_memory() and "of the memory available" in source


def test_a_container_memory_limit_caps_the_available_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "max").write_text(f"{1024 * MIB}\n")
    (tmp_path / "current").write_text(f"{256 * MIB}\n")
    (tmp_path / "unlimited").write_text("max\n")
    monkeypatch.setattr(memory, "CGROUP_FILES", ((tmp_path / "unlimited", tmp_path / "current"),))
    machine = available_memory()
    monkeypatch.setattr(memory, "CGROUP_FILES", ((tmp_path / "max", tmp_path / "current"),))
    assert available_memory() == min(machine, 768 * MIB)


def test_the_failure_names_the_estimate_the_limit_and_what_to_change() -> None:
    needed = fit_memory(
        FitConfig(hidden=(4096, 4096)),
        n_tasks=2,
        n_states=100,
        n_actions=4,
        n_features=2,
        n_steps=50,
        n_mdps=1,
    )
    sentence = str(OverBudget(needed, 1024 * MIB, "METAIRL_WORKER_MAX_MEMORY_MB"))
    assert sentence.startswith(f"The job needs an estimated {needed.total / MIB:,.0f} MiB of memory, ")
    assert "more than the 1,024 MiB this worker allows (METAIRL_WORKER_MAX_MEMORY_MB)" in sentence
    assert "config.hidden" in sentence and sentence.endswith("or run it on a worker with more memory.")
