"""Hold out a seeded fraction of each task's demonstrated steps to pick the stopping step by likelihood.

Why: the training loss is no stopping signal (a few demonstrations are overfit and the reward drifts
after an early peak); the held-out negative log-likelihood needs no knowledge of the true reward.

A deterministic demonstrator's repeated steps are counted once (`repeats_its_decisions`): where a
demonstrator always takes the same action in a state, a second visit adds no evidence about its reward, yet
counted as a step it doubles that state's weight in the likelihood, so the states it lingers in (a place it
camps at, a demonstration cut at its step limit) dominate the fit and its held-out steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from metairl_engine.demos import Trajectory, state_action_pairs, with_stays_at_ends


@dataclass(frozen=True)
class Steps:
    """Demonstrated steps of several tasks, flattened: ``tasks``, ``states``, ``actions`` all (N,) int64."""

    tasks: np.ndarray
    states: np.ndarray
    actions: np.ndarray

    def __len__(self) -> int:
        return int(self.tasks.shape[0])


DETERMINISTIC_SHARE = 0.95
"""`repeats_its_decisions`: the share of revisited states at which every visit took the same action. A
softmax demonstrator of the benchmark families repeats its action at 6–21 % of the states it revisits, the
synthetic patients' recordings at 25–84 %, the optimal policy at all of them."""

MIN_REVISITED = 10
"""`repeats_its_decisions` says no with fewer revisited states than this: too few to tell."""


def distinct_steps(states: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each distinct (state, action) pair once, in the order of its first occurrence."""
    _, first = np.unique(np.stack([states, actions]), axis=1, return_index=True)
    first = np.sort(first)
    return states[first], actions[first]


def repeats_its_decisions(demonstrations: Sequence[Sequence[Trajectory]]) -> bool:
    """Whether the demonstrator acts deterministically: at ≥ DETERMINISTIC_SHARE of the (task, state) pairs
    visited more than once (at least MIN_REVISITED of them), every visit took the same action."""
    revisited = same = 0
    for trajectories in demonstrations:
        states, actions = state_action_pairs(trajectories)
        visits = np.bincount(states)
        n_actions = np.bincount(distinct_steps(states, actions)[0], minlength=len(visits))
        revisited += int((visits >= 2).sum())
        same += int(((visits >= 2) & (n_actions == 1)).sum())
    return revisited >= MIN_REVISITED and same >= DETERMINISTIC_SHARE * revisited


def split_steps(
    demonstrations: Sequence[Sequence[Trajectory]],
    *,
    fraction: float,
    seed: int,
    fold: int = 0,
    distinct: bool = False,
) -> tuple[Steps, Steps]:
    """(train, held-out) steps: m = ⌊fraction·n⌋ random steps of each task's n are held out, ≥ 1 kept.

    Fold k holds out positions k·m … (k+1)·m − 1 (mod n) of one seeded permutation of each task's steps,
    so the folds 0 … ⌈1/fraction⌉ − 1 of one seed hold out disjoint steps (k-fold cross-fitting). With
    ``distinct`` a task's steps are its distinct (state, action) pairs (`distinct_steps`).
    """
    rng = np.random.default_rng(seed)
    parts: dict[bool, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {True: [], False: []}
    for t, trajectories in enumerate(demonstrations):
        states, actions = state_action_pairs(trajectories)
        if distinct:
            states, actions = distinct_steps(states, actions)
        n = len(actions)
        held = np.zeros(n, dtype=bool)
        m = min(int(fraction * n), n - 1)
        held[rng.permutation(n)[(fold * m + np.arange(m)) % n]] = True
        for is_held in (False, True):
            keep = held == is_held
            parts[is_held].append((np.full(int(keep.sum()), t, dtype=np.int64), states[keep], actions[keep]))

    def stack(rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> Steps:
        return Steps(*(np.concatenate([r[k] for r in rows]) for k in range(3)))

    return stack(parts[False]), stack(parts[True])


DEMONSTRATION_FOLDS = 3
"""The most folds `demonstration_folds` splits each task's demonstrations into."""


def demonstration_folds(
    demonstrations: Sequence[Sequence[Trajectory]],
    *,
    stays: Sequence[np.ndarray] | None = None,
) -> list[tuple[list[list[Trajectory]], list[list[Trajectory]]]]:
    """(train, held-out) demonstrations per task, for each of K = min(3, fewest per task) folds: fold k holds
    out each task's demonstrations i with i mod K = k, so every demonstration is held out exactly once.

    Whole demonstrations, not steps: a held-out demonstration starts where the training ones may not have
    gone, so its likelihood tests how a reward extrapolates off the demonstrations. Needs ≥ 2 per task.
    ``stays`` (per task, `planning.stay_actions` of its MDP): a held-out demonstration that ended by choice
    among all its task's demonstrations is scored with its stay (`demos.with_stays_at_ends`), the evidence the
    fits learn from (`FitConfig.stay_at_ends`); the training ones are as given, for a fit adds its own."""
    n_folds = min(DEMONSTRATION_FOLDS, min(len(t) for t in demonstrations))
    scored = (
        demonstrations
        if stays is None
        else [with_stays_at_ends(t, stay) for t, stay in zip(demonstrations, stays, strict=True)]
    )
    return [
        (
            [[tr for i, tr in enumerate(t) if i % n_folds != k] for t in demonstrations],
            [[tr for i, tr in enumerate(t) if i % n_folds == k] for t in scored],
        )
        for k in range(n_folds)
    ]


def demonstration_nlls(policies: np.ndarray, held: Sequence[Sequence[Trajectory]]) -> np.ndarray:
    """Per held-out demonstration (tasks in order): the NLL of its actions under its task's policy
    (T, S, A), summed over its steps; an (N,) array."""
    totals = []
    for policy, trajectories in zip(policies, held, strict=True):
        for tr in trajectories:
            states, actions = state_action_pairs([tr])
            totals.append(float(-np.log(np.maximum(policy[states, actions], 1e-12)).sum()))
    return np.asarray(totals)


def predicts_better(challenger: np.ndarray, incumbent: np.ndarray) -> bool:
    """True if the challenger's policies give the held-out demonstrations (the same ones, per demonstration
    NLLs) a higher likelihood than the incumbent's: neither model is preferred on a tie of evidence."""
    return bool(challenger.sum() < incumbent.sum())
