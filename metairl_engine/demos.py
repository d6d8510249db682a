"""Demonstrations: trajectories of (state, action) pairs per task, checked against the task's MDP.

numpy only, shared by the API (validation at upload) and the fit (stacked state-action pairs).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from metairl_engine.errors import Issue, check
from metairl_engine.mdp import MAX_ISSUES, MDP


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One demonstration: ``states`` (T,) or (T+1,) int64 and ``actions`` (T,) int64.

    ``states[t]`` is where action ``actions[t]`` was taken; an extra final state (no action) may follow.
    """

    states: np.ndarray
    actions: np.ndarray

    @classmethod
    def of(cls, states: Sequence[int] | np.ndarray, actions: Sequence[int] | np.ndarray) -> Trajectory:
        """Build from integer sequences (whole floats such as 3.0 too); `InvalidInput` naming the first value
        that is not a whole number, which a cast would truncate to another state. Indices and steps are
        `validate_trajectories`'s to check."""
        return cls(_indices(states, "/states"), _indices(actions, "/actions"))


def _indices(values: Sequence[int] | np.ndarray, pointer: str) -> np.ndarray:
    """``values`` as int64; `InvalidInput` at ``pointer`` unless flat, at ``pointer/k`` for the first that is not
    a whole number."""
    array = np.asarray(values)
    if array.ndim != 1:
        check([Issue(pointer, f"must be a flat list of integers, not an array of shape {array.shape}")])
    if array.dtype.kind in "iub":
        return array.astype(np.int64)
    if array.dtype.kind != "f":
        check([Issue(pointer, f"must be a list of integers, not {array.dtype} values")])
    whole = np.isfinite(array) & (np.floor(array) == array)
    if not whole.all():
        k = int(np.flatnonzero(~whole)[0])
        check([Issue(f"{pointer}/{k}", f"{array.flat[k]} is not a whole number (an index)")])
    return array.astype(np.int64)


def validate_trajectories(
    mdp: MDP, trajectories: Sequence[Trajectory], *, pointer: str = "/trajectories"
) -> None:
    """Raise `InvalidInput` naming trajectory and step of every bad index or impossible step.

    Checks: at least one trajectory; each has ≥ 1 action; len(states) is len(actions) or one more;
    indices in range; and ``P(states[t+1] | states[t], actions[t]) > 0`` wherever a next state exists.
    All checks are vectorised over the concatenated steps (no Python loop over steps).
    """
    issues: list[Issue] = []
    if len(trajectories) == 0:
        check([Issue(pointer, "needs at least one trajectory")])
    for j, tr in enumerate(trajectories):
        at = f"{pointer}/{j}"
        if not isinstance(tr.states, np.ndarray) or not isinstance(tr.actions, np.ndarray):
            issues.append(
                Issue(at, "states and actions must be numpy arrays (build them with Trajectory.of)")
            )
            continue
        if tr.states.ndim != 1 or tr.actions.ndim != 1:
            issues.append(Issue(at, "states and actions must be flat lists of integers"))
            continue
        if tr.states.dtype.kind not in "iu" or tr.actions.dtype.kind not in "iu":
            issues.append(
                Issue(at, "states and actions must be integer arrays (build them with Trajectory.of)")
            )
            continue
        if len(tr.actions) == 0:
            issues.append(Issue(f"{at}/actions", "needs at least one action"))
        elif len(tr.states) not in (len(tr.actions), len(tr.actions) + 1):
            issues.append(
                Issue(
                    f"{at}/states",
                    f"has {len(tr.states)} entries for {len(tr.actions)} actions; "
                    "give one state per action, optionally plus the final state",
                )
            )
        for name, arr, hi in (("states", tr.states, mdp.n_states), ("actions", tr.actions, mdp.n_actions)):
            if arr.ndim == 1:
                for t in np.flatnonzero((arr < 0) | (arr >= hi))[:MAX_ISSUES]:
                    issues.append(Issue(f"{at}/{name}/{t}", f"{arr[t]} is outside 0..{hi - 1} (step {t})"))
        if len(issues) >= MAX_ISSUES:
            break
    check(issues[:MAX_ISSUES])

    # Every step that has a successor: (trajectory j, step t) with t + 1 < len(states).
    traj_ids, steps, s, a, s_next = [], [], [], [], []
    for j, tr in enumerate(trajectories):
        n = min(len(tr.actions), len(tr.states) - 1)
        if n > 0:
            traj_ids.append(np.full(n, j))
            steps.append(np.arange(n))
            s.append(tr.states[:n])
            a.append(tr.actions[:n])
            s_next.append(tr.states[1 : n + 1])
    if not s:
        return
    ok = mdp.possible(np.concatenate(s), np.concatenate(a), np.concatenate(s_next))
    cat = [np.concatenate(x) for x in (traj_ids, steps, s, a, s_next)]
    for k in np.flatnonzero(~ok)[:MAX_ISSUES]:
        j, t, st, ac, nx = (int(c[k]) for c in cat)
        issues.append(
            Issue(
                f"{pointer}/{j}/states/{t + 1}",
                f"trajectory {j} step {t}: action {ac} from state {st} cannot lead to state {nx} "
                "(transition probability 0)",
            )
        )
    check(issues)


def state_action_pairs(trajectories: Sequence[Trajectory]) -> tuple[np.ndarray, np.ndarray]:
    """All demonstrated (state, action) pairs of a task, concatenated: two (N,) int64 arrays."""
    states = np.concatenate([tr.states[: len(tr.actions)] for tr in trajectories])
    actions = np.concatenate([tr.actions for tr in trajectories])
    return states.astype(np.int64), actions.astype(np.int64)


def ended_by_choice(trajectories: Sequence[Trajectory]) -> np.ndarray:
    """Which of a task's demonstrations (with their final state) ended where the demonstrator chose to stop:
    where their lengths differ, those shorter than the task's longest and those ending where another of them
    ends. (N,) bool.

    A step limit cuts every demonstration at one length, so where all are equally long none is known to have
    stopped by choice, even where two happen to end at one state; otherwise a demonstration that stops
    sooner than the limit, or at a state another also stops at, stopped because it was done."""
    lengths = np.array([len(t.actions) for t in trajectories])
    if lengths.min() == lengths.max():
        return np.zeros(len(trajectories), dtype=bool)
    has_end = np.array([len(t.states) == len(t.actions) + 1 for t in trajectories])
    ends = np.array([int(t.states[-1]) if h else -1 for t, h in zip(trajectories, has_end, strict=True)])
    _, inverse, counts = np.unique(ends, return_inverse=True, return_counts=True)
    shared_end = counts[inverse] >= 2
    return has_end & ((lengths < lengths.max()) | shared_end)


def chosen_ends(trajectories: Sequence[Trajectory]) -> np.ndarray:
    """The distinct final states of the demonstrations that `ended_by_choice`: (E,) int64. A stop by choice
    says where the task itself wants to be, its goal."""
    chosen = ended_by_choice(trajectories)
    return np.unique([int(t.states[-1]) for t, c in zip(trajectories, chosen, strict=True) if c]).astype(
        np.int64
    )


def with_stays_at_ends(trajectories: Sequence[Trajectory], stay: np.ndarray) -> list[Trajectory]:
    """The task's demonstrations, each that `ended_by_choice` one step longer: the stay action at its final
    state (``stay``: `planning.stay_actions`, -1 where there is none: nothing added).

    The likelihood of the demonstrated actions alone discards where a demonstration ends, the plainest
    evidence of its goal; a demonstrator that stopped there by choice would stay there."""
    out = []
    for t, stopped in zip(trajectories, ended_by_choice(trajectories), strict=True):
        action = int(stay[t.states[-1]]) if stopped else -1
        if action >= 0:
            t = Trajectory(np.append(t.states, t.states[-1]), np.append(t.actions, action))
        out.append(t)
    return out
