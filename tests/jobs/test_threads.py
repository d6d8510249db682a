"""Torch threads per job: small fits get one thread, large ones the cores the worker owns."""

import os

from worker.runner import SMALL_PROBLEM, torch_threads


def test_small_fits_run_on_one_thread() -> None:
    assert torch_threads(1, size=SMALL_PROBLEM - 1) == 1


def test_large_fits_share_the_owned_cores_between_concurrent_jobs() -> None:
    cores = len(os.sched_getaffinity(0))
    assert torch_threads(1, size=80_000 * 8) == cores
    assert torch_threads(cores, size=80_000 * 8) == 1
