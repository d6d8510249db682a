"""What a fit takes and gives back: `TaskData` in, `Progress` every step, `FitResult` at the end.

Plain dataclasses over numpy arrays (no torch), importable from `metairl_engine.fit` as well.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from metairl_engine.config import FitConfig
from metairl_engine.demos import Trajectory
from metairl_engine.mdp import MDP


@dataclass(frozen=True)
class TaskData:
    """One task: its MDP and the demonstrator's trajectories on it."""

    mdp: MDP
    trajectories: Sequence[Trajectory]
    name: str = ""


@dataclass(frozen=True)
class Progress:
    """The state of a fit after one optimisation step (losses are per task, averaged over tasks)."""

    step: int
    max_steps: int
    loss: float
    irl_loss: float
    sharing_loss: float
    heldout_nll: float | None
    elapsed_s: float


@dataclass(frozen=True)
class FitResult:
    """Learned rewards of T tasks on S states with A actions, all float32.

    ``baseline`` (S,), ``rewards`` (T, S), ``values`` (T, S), ``policies`` (T, S, A) = softmax(b·Q);
    ``history`` has one `Progress` per step; ``best_step`` is the step whose parameters were kept (the
    parameters that step evaluated, before its update). ``baseline`` is the baseline network's reward, or
    the mean of the task rewards where no baseline is learned (``sharing="none"``, ``method="maxent"``).
    ``baseline_spread`` (S,) and ``reward_spread`` (T, S): per state, the standard deviation of the
    (mean-centred) reward across the ensemble's members, how much members fitted to different folds of
    the demonstrations disagree there; None where one member was fitted (``ensemble`` 1, ``maxent``).
    """

    baseline: np.ndarray
    rewards: np.ndarray
    values: np.ndarray
    policies: np.ndarray
    history: list[Progress]
    best_step: int
    config: FitConfig
    baseline_spread: np.ndarray | None = None
    reward_spread: np.ndarray | None = None
