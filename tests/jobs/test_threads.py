"""Torch threads per job: small fits get one thread, large ones the cores the worker owns; threads spin briefly."""

import os
from pathlib import Path

import pytest

from worker.main import prepare_environment
from worker.runner import SMALL_PROBLEM, torch_threads, usable_cores


def test_small_fits_run_on_one_thread() -> None:
    assert torch_threads(1, size=SMALL_PROBLEM - 1) == 1


def test_large_fits_share_the_owned_cores_between_concurrent_jobs() -> None:
    cores = len(os.sched_getaffinity(0))
    assert torch_threads(1, size=80_000 * 8) == cores
    assert torch_threads(cores, size=80_000 * 8) == 1


def test_a_thread_setting_overrides_the_count_for_large_fits_only() -> None:
    assert torch_threads(1, size=80_000 * 8, threads=3) == 3
    assert torch_threads(1, size=SMALL_PROBLEM - 1, threads=3) == 1


@pytest.mark.parametrize(
    ("cpu_max", "expected"),
    [
        ("max 100000\n", None),
        ("100000 100000\n", 1),
        ("150000 100000\n", 1),
        ("50000 100000\n", 1),
        ("250000 100000\n", 2),
    ],
)
def test_a_cgroup_cpu_quota_caps_the_usable_cores(tmp_path: Path, cpu_max: str, expected: int | None) -> None:
    quota = tmp_path / "cpu.max"
    quota.write_text(cpu_max)
    cores = len(os.sched_getaffinity(0))
    assert usable_cores(quota) == (cores if expected is None else min(cores, expected))


def test_without_a_cgroup_quota_file_the_affinity_counts(tmp_path: Path) -> None:
    assert usable_cores(tmp_path / "missing") == len(os.sched_getaffinity(0))


def test_the_worker_makes_openmp_threads_spin_briefly_unless_told_otherwise(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("GOMP_SPINCOUNT", raising=False)
    monkeypatch.delenv("METAIRL_WORKER_CONCURRENCY", raising=False)
    prepare_environment(concurrency=3)
    assert os.environ["GOMP_SPINCOUNT"] == "3000"
    assert os.environ["METAIRL_WORKER_CONCURRENCY"] == "3"
    monkeypatch.setenv("GOMP_SPINCOUNT", "300000")
    prepare_environment(concurrency=1)
    assert os.environ["GOMP_SPINCOUNT"] == "300000"
