"""Where a worker runs its fits (``METAIRL_WORKER_DEVICE``): the setting, and how it becomes a torch device."""

from __future__ import annotations

import pytest
import torch
from pydantic import ValidationError

from service.settings import Settings
from worker.runner import NoCuda, explain_failure, fit_device

NO_CUDA = pytest.mark.skipif(torch.cuda.is_available(), reason="torch sees a CUDA GPU on this machine")


def test_worker_device_is_read_from_the_environment_and_defaults_to_auto(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("METAIRL_WORKER_DEVICE", raising=False)
    assert Settings().worker_device == "auto"
    monkeypatch.setenv("METAIRL_WORKER_DEVICE", "cuda")
    assert Settings().worker_device == "cuda"
    monkeypatch.setenv("METAIRL_WORKER_DEVICE", "gpu")
    with pytest.raises(ValidationError, match="worker_device"):
        Settings()


@NO_CUDA
def test_auto_fits_on_the_cpu_when_torch_sees_no_cuda_gpu() -> None:
    assert fit_device("auto") == "cpu"


def test_auto_fits_on_cuda_when_torch_sees_a_gpu_and_cpu_stays_on_the_cpu(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert fit_device("auto") == "cuda"
    assert fit_device("cuda") == "cuda"
    assert fit_device("cpu") == "cpu"


@NO_CUDA
def test_cuda_without_a_gpu_fails_the_job_with_a_message_naming_the_setting() -> None:
    with pytest.raises(NoCuda) as exc:
        fit_device("cuda")
    reason = explain_failure(exc.value, task_ids=[], settings=Settings())
    assert reason == str(exc.value)
    assert "METAIRL_WORKER_DEVICE=cuda" in reason and "torch sees no CUDA GPU" in reason
