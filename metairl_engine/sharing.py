"""Reward-sharing losses (paper §III-C): how far each task reward r_i strays from the baseline r_b.

The paper writes L(r_i, r_b) = log Z − D(r_i, r_b) with P(r_i | r_b) ∝ exp(D); taken literally that
*rewards* large differences and diverges. We implement the stated intent (§I: demonstrators change the
inherent reward minimally), so every loss below is small when r_i stays close to r_b:

- ``l2``: mean of (r_i − r_b)² (the squared L2 norm, per state, so the weight does not scale with S);
- ``huber``: mean Huber loss with δ = 1 of r_i − r_b;
- ``std``: standard deviation of r_i − r_b (a constant offset is free);
- ``entropy``: log|S_i| − H(softmax(r_i − r_b)), i.e. MAXIMISE the entropy of the softmax of the
  differences (a uniform softmax, entropy log|S_i|, means the differences are all equal).

Differences come as one flat vector over rows (task, state) with each row's task id, so the same code
serves "all states" and "the task's visited states" (a different number of states per task).
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from metairl_engine.config import Sharing


def segment_sum(x: torch.Tensor, task: torch.Tensor, n_tasks: int) -> torch.Tensor:
    """Per-task sums (T,) of row values ``x`` (M,) with task ids ``task`` (M,)."""
    return torch.zeros(n_tasks, dtype=x.dtype, device=x.device).index_add(0, task, x)


def sharing_loss(diff: torch.Tensor, task: torch.Tensor, *, n_tasks: int, kind: Sharing) -> torch.Tensor:
    """Per-task sharing loss (T,) of the differences ``diff`` = r_i(s) − r_b(s) over rows (M,)."""
    count = segment_sum(torch.ones_like(diff), task, n_tasks)
    if kind == "none":
        return torch.zeros(n_tasks, dtype=diff.dtype, device=diff.device)
    if kind == "l2":
        return segment_sum(diff * diff, task, n_tasks) / count
    if kind == "huber":
        return (
            segment_sum(
                F.huber_loss(diff, torch.zeros_like(diff), reduction="none", delta=1.0), task, n_tasks
            )
            / count
        )
    if kind == "std":
        centred = diff - (segment_sum(diff, task, n_tasks) / count)[task]
        return torch.sqrt(segment_sum(centred * centred, task, n_tasks) / count + 1e-12)
    # entropy: log n − H(p) with p = softmax of the task's differences, computed stably per task.
    peak = torch.zeros(n_tasks, dtype=diff.dtype, device=diff.device).scatter_reduce(
        0, task, diff.detach(), reduce="amax", include_self=False
    )
    shifted = diff - peak[task]
    log_norm = torch.log(segment_sum(torch.exp(shifted), task, n_tasks))
    log_p = shifted - log_norm[task]
    entropy = -segment_sum(torch.exp(log_p) * log_p, task, n_tasks)
    return torch.log(count) - entropy
