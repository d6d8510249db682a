"""Reward-sharing losses: zero when task rewards equal the baseline, growing with the departure."""

from __future__ import annotations

import pytest
import torch

from metairl_engine.sharing import sharing_loss

KINDS = ["l2", "huber", "std", "entropy"]


@pytest.mark.parametrize("kind", KINDS)
def test_loss_is_zero_without_differences_and_positive_with_them(kind: str) -> None:
    task = torch.tensor([0, 0, 0, 1, 1])
    zero = sharing_loss(torch.zeros(5), task, n_tasks=2, kind=kind)  # type: ignore[arg-type]
    assert torch.allclose(zero, torch.zeros(2), atol=1e-5)
    diff = torch.tensor([0.0, 2.0, -1.0, 0.0, 0.0])
    loss = sharing_loss(diff, task, n_tasks=2, kind=kind)  # type: ignore[arg-type]
    assert loss[0] > 0.01 and abs(float(loss[1])) < 1e-5


@pytest.mark.parametrize("kind", ["std", "entropy"])
def test_shift_invariant_losses_ignore_a_constant_offset(kind: str) -> None:
    task = torch.zeros(4, dtype=torch.long)
    diff = torch.tensor([0.3, -1.0, 2.0, 0.5])
    a = sharing_loss(diff, task, n_tasks=1, kind=kind)  # type: ignore[arg-type]
    b = sharing_loss(diff + 5.0, task, n_tasks=1, kind=kind)  # type: ignore[arg-type]
    assert torch.allclose(a, b, atol=1e-5)


def test_huber_is_quadratic_near_zero_and_linear_far_away() -> None:
    task = torch.zeros(1, dtype=torch.long)
    assert float(sharing_loss(torch.tensor([0.5]), task, n_tasks=1, kind="huber")) == pytest.approx(0.125)
    assert float(sharing_loss(torch.tensor([3.0]), task, n_tasks=1, kind="huber")) == pytest.approx(2.5)


def test_none_is_always_zero() -> None:
    task = torch.zeros(3, dtype=torch.long)
    assert float(sharing_loss(torch.tensor([1.0, 5.0, -2.0]), task, n_tasks=1, kind="none").sum()) == 0.0
