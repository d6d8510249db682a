"""`fit`: learn every task's reward and the shared baseline reward (Li & Burdick, Algorithm 1).

Read top to bottom, `_fit_meta_irl` is the whole method:

1. per task i a VR network f_i(s) = r_i(s) + γ V_i(s)                         (paper eq. 5)
2. Q_i(s, a) = Σ_s' P_i(s'|s, a) f_i(s')  — a gather or a sparse matmul      (eq. 6)
3. V_i(s) = backup_a Q_i(s, a)  — max, logsumexp or BGI                       (eq. 7)
4. r_i(s) = f_i(s) − γ V_i(s)                                                 (eq. 8)
5. IRL loss: NLL of demonstrated actions under softmax(b·Q_i(s, ·))           (eq. 9–10)
6. sharing loss: keep r_i close to the baseline network r_b(s)                (§III-C, see sharing.py)
7. minimise mean_i [IRL_i + w·sharing_i] over all networks jointly with Adam   (eq. 1, Algorithm 1)

No Bellman equation is ever solved. All tasks are evaluated in single batched tensor ops. The parameters
kept are those of the step with the best held-out NLL (holdout.py explains why).
"""

from __future__ import annotations

import math
import sys
import time
import types
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from metairl_engine.backups import QRows, backup, successor_pairs
from metairl_engine.config import (
    FitConfig,
    baseline_column_issues,
    chooses_tabular_method,
    ensemble_size,
    sharing_block_count,
)
from metairl_engine.coordinates import COORDINATE_OCTAVES, features_are_positions, state_coordinates
from metairl_engine.demos import Trajectory, validate_trajectories, with_stays_at_ends
from metairl_engine.errors import Cancelled, Diverged, InvalidInput, Issue, check
from metairl_engine.evidence import NEXT_TO_VISITED
from metairl_engine.holdout import (
    Steps,
    demonstration_folds,
    demonstration_nlls,
    predicts_better,
    repeats_its_decisions,
    split_steps,
)
from metairl_engine.mdp import MDP
from metairl_engine.memory import EVAL_CHUNK, TRAIN_CHUNK, retained_heap
from metairl_engine.networks import StackedMLP, fourier_features
from metairl_engine.planning import stay_actions, transition_matrix
from metairl_engine.results import FitResult, Progress, TaskData
from metairl_engine.sharing import segment_sum, sharing_loss
from metairl_engine.shrinkage import BUDGET as SHRINK_BUDGET
from metairl_engine.shrinkage import shrink_deviations

__all__ = ["FitResult", "Progress", "TaskData", "fit"]

ProgressCallback = Callable[[Progress], None]
StopCheck = Callable[[], bool]

CONVERGED_STEPS = 10
"""The loss has converged when its change stayed within ``tolerance`` this many steps in a row: Adam's loss
oscillates, and one step's change can vanish by chance where the loss turns (an 80,000-state fit stopped at
step 67 so; run on, it went to step 875)."""


def fit(
    tasks: Sequence[TaskData],
    config: FitConfig = FitConfig(),
    *,
    progress: ProgressCallback | None = None,
    should_stop: StopCheck | None = None,
    device: str | torch.device | None = None,
) -> FitResult:
    """Learn a reward per task and the demonstrator's baseline reward; raises InvalidInput or Cancelled.

    ``device`` ("cpu", "cuda", "cuda:1"; None: the CPU) is where the meta-IRL method's tensors live; the
    result is numpy either way. The networks are initialised on the CPU, so a seed gives the same starting
    weights on every device. The tabular methods (``maxent``, ``shared_maxent``) always run on the CPU (their
    planning is numpy/scipy). On an MDP without features the held-out demonstrations may choose the
    ``shared_maxent`` solver instead
    (`FitConfig.tabular_choice`); the result's ``config`` says which ran.
    """
    if not isinstance(config, FitConfig):
        check(
            [
                Issue(
                    "/config",
                    f"must be a FitConfig (FitConfig.from_dict reads a dict), not {type(config).__name__}",
                )
            ]
        )
    validate_tasks(tasks)
    if config.method != "meta_irl":
        from metairl_engine.maxent import fit_maxent

        return fit_maxent(tasks, config, progress=progress, should_stop=should_stop)
    try:
        on = torch.device(device or "cpu")
        torch.empty(0, device=on)  # a device torch names but this machine lacks fails here, not mid-fit
    except (RuntimeError, TypeError, AssertionError) as exc:  # torch asserts when built without CUDA
        check(
            [Issue("/device", f"{device!r} is not a device torch can use here ({str(exc).splitlines()[0]})")]
        )
    with retained_heap():
        if tabular_choice_applies(tasks, config):
            return _fit_choosing_method(tasks, config, progress=progress, should_stop=should_stop, device=on)
        return _fit_choosing_task_inputs(tasks, config, progress=progress, should_stop=should_stop, device=on)


def tabular_choice_applies(tasks: Sequence[TaskData], config: FitConfig) -> bool:
    """`FitConfig.tabular_choice` is made (`config.chooses_tabular_method`) and every task has a
    demonstration to hold out and one to keep. Features count as none where they only say where a state is
    on an MDP without a layout (`coordinates.features_are_positions`: each cell's (x, y) as a lab may upload
    it); a grid with a layout keeps its coordinates as features without the choice, whose folds would cost
    several fits on every terrain and velocity grid (docs/method.md, "Features that only say where a state
    is")."""
    mdps = [t.mdp for t in tasks]
    features = mdps[0].features
    featureless = features is None or (
        all(m.layout is None for m in mdps) and features_are_positions(mdps, features)
    )
    return chooses_tabular_method(config, has_features=not featureless) and all(
        len(t.trajectories) >= 2 for t in tasks
    )


def task_stays(tasks: Sequence[TaskData]) -> list[np.ndarray]:
    """Per task, its MDP's stay action per state (`planning.stay_actions`), computed once per distinct MDP."""
    per_mdp = {key: stay_actions(mdp) for key, mdp in {id(t.mdp): t.mdp for t in tasks}.items()}
    return [per_mdp[id(t.mdp)] for t in tasks]


def _fit_choosing_method(
    tasks: Sequence[TaskData],
    config: FitConfig,
    *,
    progress: ProgressCallback | None,
    should_stop: StopCheck | None,
    device: torch.device,
) -> FitResult:
    """`FitConfig.tabular_choice`: in each fold of the demonstrations (`demonstration_folds`: every one held
    out once), fit the networks and the ``maxent`` solver on the rest; where the solver predicts the held-out
    demonstrations better, fit ``shared_maxent`` on every demonstration, else refit the networks. The probe is
    the solver that extrapolates nothing, each task alone: the question is whether the coordinates'
    extrapolation predicts where new demonstrations go, and the answer keeps the sharing the config asks for.
    With `FitConfig.stay_at_ends` a held-out demonstration that ended by choice is scored with its stay, as
    the fits count it, so a model whose policy walks away from where the demonstrations stop is charged for
    it. Progress runs over the 2K + 1 fits."""
    from metairl_engine.maxent import fit_maxent

    stays = task_stays(tasks) if config.stay_at_ends else None
    folds = demonstration_folds([t.trajectories for t in tasks], stays=stays)
    networks, probe = replace(config, tabular_choice=False), replace(config, method="maxent")
    n_stages = 2 * len(folds) + 1

    def stage(index: int) -> ProgressCallback:
        """Progress of fit ``index`` (0 … 2K) as its share of the whole."""

        def report(p: Progress) -> None:
            if progress is not None:
                step = index * config.max_steps + min(
                    config.max_steps, p.step * config.max_steps // p.max_steps
                )
                progress(replace(p, step=step, max_steps=n_stages * config.max_steps))

        return report

    networks_nll, solver_nll = [], []
    for k, (train, held) in enumerate(folds):
        train_tasks = [replace(t, trajectories=demos) for t, demos in zip(tasks, train, strict=True)]
        learned = _fit_choosing_task_inputs(
            train_tasks, networks, progress=stage(2 * k), should_stop=should_stop, device=device
        )
        tabular = fit_maxent(train_tasks, probe, progress=stage(2 * k + 1), should_stop=should_stop)
        networks_nll.append(demonstration_nlls(learned.policies, held))
        solver_nll.append(demonstration_nlls(tabular.policies, held))
    last = stage(n_stages - 1)
    if predicts_better(np.concatenate(solver_nll), np.concatenate(networks_nll)):
        shared = replace(config, method="shared_maxent")
        return fit_maxent(tasks, shared, progress=last, should_stop=should_stop)
    return _fit_choosing_task_inputs(tasks, networks, progress=last, should_stop=should_stop, device=device)


def _fit_choosing_task_inputs(
    tasks: Sequence[TaskData],
    config: FitConfig,
    *,
    progress: ProgressCallback | None,
    should_stop: StopCheck | None,
    device: torch.device,
) -> FitResult:
    """`FitConfig.task_features`: with ``auto``, where there is a choice (sharing, a hold-out, two tasks or
    more, and a place the features do not already hold: `place_inputs`), fit with both and keep the place
    alone only if its held-out NLL (on the same held-out steps: the folds depend on the seed alone) is lower
    than the other's by more than one standard error of the other's per-step NLLs; else the features and
    the place, the inputs every family was first measured with. The choice made is the result's
    ``config.task_features``, so refitting with that config gives the same result. Progress runs over both
    fits (steps of the second follow ``max_steps`` of the first)."""
    if config.task_features != "auto":
        return _fit_meta_irl(tasks, config, progress=progress, should_stop=should_stop, device=device)[0]
    with_features = replace(config, task_features="yes")
    features = tasks[0].mdp.features
    if (
        config.sharing == "none"
        or config.holdout_fraction == 0
        or len(tasks) < 2
        or features is None
        or place_inputs(input_units(features, [t.mdp for t in tasks]), tasks, config) is None
    ):
        return _fit_meta_irl(tasks, with_features, progress=progress, should_stop=should_stop, device=device)[
            0
        ]
    total = 2 * config.max_steps  # what progress reports cover

    def first(p: Progress) -> None:
        if progress is not None:
            progress(replace(p, max_steps=total))

    def second(p: Progress) -> None:
        if progress is not None:
            progress(replace(p, step=p.step + config.max_steps, max_steps=total))

    featured, featured_nll = _fit_meta_irl(
        tasks, with_features, progress=first, should_stop=should_stop, device=device
    )
    placed, placed_nll = _fit_meta_irl(
        tasks, replace(config, task_features="no"), progress=second, should_stop=should_stop, device=device
    )
    if featured_nll is None or placed_nll is None:  # no held-out step: nothing to choose by
        return featured
    return placed if place_wins(featured_nll, placed_nll) else featured


def place_wins(with_features: torch.Tensor, place_alone: torch.Tensor) -> bool:
    """True if the held-out NLLs per step of the place alone have a mean below those with the features by more
    than one standard error of the latter: the one-standard-error rule of the stopping and the shrinkage,
    favouring the inputs every benchmark family was first measured with."""
    standard_error = float(with_features.std()) / with_features.numel() ** 0.5
    return float(with_features.mean() - place_alone.mean()) > standard_error


def validate_tasks(tasks: Sequence[TaskData]) -> None:
    """All tasks must share states, actions and features; every task's trajectories must fit its MDP."""
    if isinstance(tasks, TaskData) or not isinstance(tasks, Sequence):
        check([Issue("/tasks", f"must be a list of TaskData, not {type(tasks).__name__}")])
    if len(tasks) == 0:
        check([Issue("/tasks", "needs at least one task")])
    for i, task in enumerate(tasks):
        if not isinstance(task, TaskData):
            check([Issue(f"/tasks/{i}", f"must be a TaskData, not {type(task).__name__}")])
        if not isinstance(task.mdp, MDP):
            check(
                [
                    Issue(
                        f"/tasks/{i}/mdp",
                        f"must be an MDP (MDP.build, grid_mdp), not {type(task.mdp).__name__}",
                    )
                ]
            )
        if not isinstance(task.trajectories, Sequence) or not all(
            isinstance(t, Trajectory) for t in task.trajectories
        ):
            check(
                [
                    Issue(
                        f"/tasks/{i}/trajectories",
                        "must be a list of Trajectory (Trajectory.of(states, actions))",
                    )
                ]
            )
    issues: list[Issue] = []
    first = tasks[0].mdp
    for i, task in enumerate(tasks):
        m = task.mdp
        issues += _unbuilt_mdp_issues(m, f"/tasks/{i}/mdp")
        if i > 0:
            for what, mine, theirs in (
                ("states", m.n_states, first.n_states),
                ("actions", m.n_actions, first.n_actions),
                ("feature columns", m.n_features, first.n_features),
            ):
                if mine != theirs:
                    issues.append(Issue(f"/tasks/{i}/mdp", f"has {mine} {what} but task 0 has {theirs}"))
            if (
                m.n_states == first.n_states
                and m.n_features == first.n_features
                and not _same_features(m, first)
            ):
                issues.append(
                    Issue(
                        f"/tasks/{i}/mdp",
                        "has different state features from task 0 (tasks must share states)",
                    )
                )
        try:
            validate_trajectories(m, task.trajectories, pointer=f"/tasks/{i}/trajectories")
        except InvalidInput as exc:
            issues += exc.issues
    check(issues)


def _unbuilt_mdp_issues(mdp: MDP, pointer: str) -> list[Issue]:
    """What `MDP.build` refuses and an MDP made with ``MDP(...)`` directly may hold, checked cheaply: features
    that are not one finite row per state, a next-state table of another shape or pointing outside the states
    (else a fit fails later as a diverged loss, blaming its settings)."""
    issues = []
    built = "(MDP.build checks an MDP's arrays; MDP(...) does not)"
    if mdp.features is not None and (
        np.ndim(mdp.features) != 2 or len(mdp.features) != mdp.n_states or not np.isfinite(mdp.features).all()
    ):
        issues.append(Issue(f"{pointer}/features", f"must be {mdp.n_states} rows of finite numbers {built}"))
    table = mdp.next_state
    if table is not None and (
        np.shape(table) != (mdp.n_states, mdp.n_actions) or table.min() < 0 or table.max() >= mdp.n_states
    ):
        issues.append(
            Issue(
                f"{pointer}/next_state",
                f"must be {mdp.n_states}×{mdp.n_actions} states in 0..{mdp.n_states - 1} {built}",
            )
        )
    return issues


def _same_features(a: MDP, b: MDP) -> bool:
    """Both tabular, or equal feature matrices."""
    if a.features is None or b.features is None:
        return a.features is None and b.features is None
    return a.features is b.features or bool(np.array_equal(a.features, b.features))


class _Problem:
    """Everything about the data that stays fixed during optimisation, as index tensors.

    An ensemble of K members is one problem of T·K networks: network j = k·T + i plays task i in member k,
    and member k holds out fold k of every task's steps; member k's baseline is row k of the baseline net.
    Built on the CPU; `to` moves it to the fit's device.
    """

    device = torch.device("cpu")
    """Where the tensors are (`to` changes it); `inputs` builds its index tensors here."""

    def __init__(self, tasks: Sequence[TaskData], config: FitConfig):
        self.n_tasks = len(tasks)
        self.n_members = ensemble_size(config, n_tasks=self.n_tasks, n_states=tasks[0].mdp.n_states)
        self.n_nets = self.n_tasks * self.n_members
        self.mdps = [t.mdp for t in tasks] * self.n_members
        self.n_states = self.mdps[0].n_states
        self.gamma = torch.tensor([m.gamma for m in self.mdps], dtype=torch.float32)
        features = self.mdps[0].features
        if features is not None:
            features = input_units(features, [t.mdp for t in tasks])
        if features is None and config.tabular_inputs == "coordinates":
            features = state_coordinates([t.mdp for t in tasks], seed=config.seed)
        base_columns = _baseline_columns(config, features)
        task_features = features
        place = None if features is None else place_inputs(features, tasks, config)
        if features is not None and place is not None:
            task_features = place if config.task_features == "no" else _joined(features, place)
        self.features = None if task_features is None else _encode(task_features, config)
        self.base_features = (
            self.features
            if features is None or (base_columns is None and task_features is features)
            else _encode(features if base_columns is None else features[:, base_columns], config)
        )
        demos = [t.trajectories for t in tasks]
        distinct = repeats_its_decisions(demos)  # the demonstrator's own decisions, before any stay is added
        if config.stay_at_ends:
            demos = [with_stays_at_ends(d, stay) for d, stay in zip(demos, task_stays(tasks), strict=True)]
        folds = [
            split_steps(demos, fraction=config.holdout_fraction, seed=config.seed, fold=k, distinct=distinct)
            for k in range(self.n_members)
        ]
        self.train = _stack_members([train for train, _ in folds], self.n_tasks)
        self.held = _stack_members([held for _, held in folds], self.n_tasks)
        held_member = self.held.tasks // self.n_tasks
        self.held_of_member = [
            torch.from_numpy(np.flatnonzero(held_member == k)) for k in range(self.n_members)
        ]

        # Rows (network, state) on which the sharing loss compares r_i with r_b: one set per block, one
        # block a step (`FitConfig.sharing_blocks`).
        if config.sharing == "none":
            shares = [Steps(*(np.zeros(0, dtype=np.int64) for _ in range(3)))]
        elif config.sharing_states == "all":
            n_blocks = sharing_block_count(config, n_states=self.n_states)
            shares = [
                _all_rows(b, self.n_nets) for b in sharing_blocks(self.mdps, n_blocks, seed=config.seed)
            ]
        else:
            visited = [np.unique(np.concatenate([tr.states for tr in t.trajectories])) for t in tasks]
            visited *= self.n_members
            share_nets = np.concatenate([np.full(len(v), j) for j, v in enumerate(visited)]).astype(np.int64)
            shares = [Steps(share_nets, np.concatenate(visited).astype(np.int64), 0 * share_nets)]
        self.train_actions = torch.from_numpy(self.train.actions)
        self.train_tasks = torch.from_numpy(self.train.tasks)
        self.held_actions = torch.from_numpy(self.held.actions)
        # Per (network, state): how much the baseline learns from the network's reward there
        # (`FitConfig.baseline_elsewhere_weight` ω; not needed at ω = 1, where every row counts 1). 1 where the
        # network's training steps visit the state, and where exactly one task of its member visits it: one
        # witness cannot tell the shared reward from its own goal, so every task counts alike. NEXT_TO_VISITED
        # (½, or ω if larger) where its steps only move next to the state: r = f − γV there rests on f at
        # successors that the demonstrated choices compare only in part. ω elsewhere.
        self.baseline_weight: np.ndarray | None = None
        if config.sharing != "none" and config.baseline_elsewhere_weight != 1.0:
            trained = np.zeros(self.n_nets * self.n_states, dtype=bool)
            trained[self.train.tasks * self.n_states + self.train.states] = True
            nets, reached = successor_pairs(self.mdps, self.train.tasks, self.train.states)
            near = np.zeros_like(trained)
            near[nets * self.n_states + reached] = True
            by_member = trained.reshape(self.n_members, self.n_tasks, self.n_states)
            one_witness = by_member.sum(axis=1, keepdims=True) == 1  # (K, 1, S)
            full = (by_member | one_witness).reshape(-1)
            elsewhere = config.baseline_elsewhere_weight
            neighbour = max(NEXT_TO_VISITED, elsewhere)
            weight = np.where(full, 1.0, np.where(near, neighbour, elsewhere))
            self.baseline_weight = weight.astype(np.float32)
        demo_tasks = np.concatenate([self.train.tasks, self.held.tasks])
        demo_states = np.concatenate([self.train.states, self.held.states])
        self.blocks = [_Block(self, share, demo_tasks, demo_states) for share in shares]

    def to(self, device: torch.device) -> _Problem:
        """Move every tensor this problem and its blocks hold to ``device`` (in place; returns self)."""
        for holder in (self, *self.blocks):
            _move_tensors(holder, device)
        self.device = device
        return self

    def inputs(self, states: np.ndarray, *, base: bool = False) -> torch.Tensor:
        """Network inputs of these states: feature rows (the baseline's own if ``base``), or the state
        indices themselves when tabular."""
        index = torch.from_numpy(states.astype(np.int64)).to(self.device)
        features = self.base_features if base else self.features
        return index if features is None else features[index]


class _Block:
    """What one step evaluates: per network j the states U_j where f_j is needed — successors of its own
    demonstrated steps, its rows of one block of sharing rows (network, state) and those rows' successors —
    and the indices that read Q, r and r_b off the networks' outputs. Each network runs on its own U_j
    (padded to the longest), not on the union of every network's: on an 80,000-state velocity grid the
    successors of the other tasks' demonstrations are most of that union."""

    def __init__(self, problem: _Problem, share: Steps, demo_tasks: np.ndarray, demo_states: np.ndarray):
        # Every (network, state) the step needs, once: sorted by network, then state.
        nets, reached = successor_pairs(
            problem.mdps,
            np.concatenate([demo_tasks, share.tasks]),
            np.concatenate([demo_states, share.states]),
        )
        needed = np.zeros(problem.n_nets * problem.n_states, dtype=bool)  # a mark per (network, state)
        needed[nets * problem.n_states + reached] = True
        needed[share.tasks * problem.n_states + share.states] = True
        keys = np.flatnonzero(needed)
        net_of, state_of = np.divmod(keys, problem.n_states)
        counts = np.bincount(net_of, minlength=problem.n_nets)
        starts = np.cumsum(counts) - counts
        position = np.arange(len(keys)) - starts[net_of]  # of each state in its network's U_j
        n_u = int(counts.max())
        # (T·K, N): row j is U_j, padded with its last state (positions past U_j are never read)
        self.states_u = np.repeat(state_of[starts + counts - 1][:, None], n_u, axis=1)
        self.states_u[net_of, position] = state_of
        columns = np.full((problem.n_nets, problem.n_states), -1, dtype=np.int64)
        columns[net_of, state_of] = position

        def rows(s: Steps) -> QRows:
            return QRows(problem.mdps, s.tasks, s.states, columns=columns, n_columns=n_u)

        self.q_train, self.q_held = rows(problem.train), rows(problem.held)
        self.share_tasks = torch.from_numpy(share.tasks)
        self.share_weight: torch.Tensor | None = None  # the baseline's weight per sharing row (`_Problem`)
        if len(share):
            self.q_share = rows(share)
            self.share_f = torch.from_numpy(share.tasks * n_u + columns[share.tasks, share.states])
            self.share_gamma = problem.gamma[self.share_tasks]  # γ of each sharing row's network
            self.base_states, base_index = np.unique(share.states, return_inverse=True)
            member = share.tasks // problem.n_tasks  # row k of the baseline network's (K, B) outputs
            self.share_base = torch.from_numpy(member * len(self.base_states) + base_index.astype(np.int64))
            self.inputs_base = problem.inputs(self.base_states, base=True)
            if problem.baseline_weight is not None:
                self.share_weight = torch.from_numpy(
                    problem.baseline_weight[share.tasks * problem.n_states + share.states]
                )
        else:
            self.base_states = np.zeros(0, dtype=np.int64)
        self.inputs_u = problem.inputs(self.states_u)  # (T·K, N, F), or (T·K, N) state indices when tabular


def _move_tensors(holder: object, device: torch.device) -> None:
    """Move every tensor attribute, `QRows` and list of tensors of ``holder`` to ``device``.

    It walks the attributes instead of naming them, so a tensor added to ``__init__`` moves too.
    """
    for name, value in list(vars(holder).items()):
        if isinstance(value, torch.Tensor | QRows):
            setattr(holder, name, value.to(device))
        elif isinstance(value, list) and value and all(isinstance(v, torch.Tensor) for v in value):
            setattr(holder, name, [v.to(device) for v in value])


def _all_rows(states: np.ndarray, n_nets: int) -> Steps:
    """Sharing rows comparing every network with the baseline on each of ``states``."""
    nets = np.repeat(np.arange(n_nets), len(states))
    return Steps(nets, np.tile(states, n_nets), 0 * nets)


def sharing_blocks(mdps: Sequence[MDP], n_blocks: int, *, seed: int) -> list[np.ndarray]:
    """All states split at random into ``n_blocks`` sorted blocks of about equal size (fewer when there are
    fewer groups of states than that).

    States with the same successors in every MDP stay in one block (on a velocity grid: the 8 directions of
    a cell), so a block's Q needs f on about as many other states as it holds, not on most of the MDP.
    """
    n_states = mdps[0].n_states
    if n_blocks == 1:
        return [np.arange(n_states)]
    group = np.arange(n_states)
    tables = [m.next_state for m in {id(m): m for m in mdps}.values() if m.next_state is not None]
    if len(tables) == len({id(m) for m in mdps}):  # every MDP deterministic: group by successor rows
        successor_rows: np.ndarray = np.concatenate(tables, axis=1)
        group = np.unique(successor_rows, axis=0, return_inverse=True)[1].reshape(-1)
    n_groups = int(group.max()) + 1
    n_blocks = min(n_blocks, n_groups)
    block_of_group = np.empty(n_groups, dtype=np.int64)
    block_of_group[np.random.default_rng(seed).permutation(n_groups)] = (
        np.arange(n_groups) * n_blocks // n_groups
    )
    block = block_of_group[group]
    return [np.flatnonzero(block == b) for b in range(n_blocks)]


def _encode(features: np.ndarray, config: FitConfig) -> torch.Tensor:
    """Network inputs from state features: the varying columns (`varying_columns`) and their Fourier waves
    (`fourier_octaves`)."""
    kept = np.ascontiguousarray(features[:, varying_columns(features)])
    return torch.from_numpy(fourier_features(kept, octaves=config.fourier_octaves))


def varying_columns(features: np.ndarray) -> np.ndarray:
    """Indices of the feature columns that are not the same on every state (all of them when none varies).

    A column constant over the states tells the networks nothing, yet each such column is one more copy of
    the first layer's bias, and Adam steps every copy by about the learning rate: k of them move that bias k
    times as fast as the real one. Objectworld's discrete features ("distance < d" for d = 1 … N) hold
    84–95 columns of ones out of 128 (docs/method.md, "Constant feature columns").
    """
    varying = np.flatnonzero((features != features[:1]).any(axis=0))
    return varying if varying.size else np.arange(features.shape[1])


MOVE_UNIT_SLACK = 1e-3
"""How far a column's largest one-move change must exceed 1, or its span fall short of 1, for `input_units` to
rescale it: float32 rounding of an exact one (a Euclidean distance in cells, a normalised coordinate) is not a
unit."""

MOVE_ELEMENTS = 1 << 22
"""Feature changes (moves × columns) `input_units` holds at once: 16 MB of float32, whatever the width."""


def input_units(features: np.ndarray, mdps: Sequence[MDP]) -> np.ndarray:
    """``features`` (S, F) with each varying column moved to start at 0 and divided by its largest change over
    one move (any action of any of ``mdps``) where that exceeds 1, else by its span where that is below 1: every
    input starts at 0, spans at least 1 and changes by at most 1 per move. The array itself when no column needs
    any of it.

    The networks' initial weights and learning rate suit inputs near zero that span about one unit or more and
    change by about one or less per move — distances in cells, indicators, normalised coordinates — and a fit
    should not depend on the units or the origin a lab records its features in. On the multi-objectworld
    family, distances in tenths of a cell (×10) gave Pearson 0.303 against 0.511 in cells, in hundreds of cells
    (×0.01) 0.276, counted from 100 cells away (+100) 0.173 (docs/method.md, "Feature units"). Every benchmark
    family's, terrain's and the motion grid's features already start at 0, span at least 1 and change by at
    most 1 per move, so they fit bit for bit as before.
    """
    smallest, largest = features.min(axis=0), features.max(axis=0)
    span = largest.astype(np.float64) - smallest
    low = np.where(span > 0, smallest, 0)  # constant columns keep their value: `varying_columns` drops them
    change = np.zeros(features.shape[1], dtype=np.float64)
    for mdp in {id(m): m for m in mdps}.values():
        if mdp.next_state is not None:
            sources = np.repeat(np.arange(mdp.n_states), mdp.n_actions)
            targets = mdp.next_state.reshape(-1)
        else:
            pairs = transition_matrix(mdp).tocoo()
            sources, targets = pairs.row // mdp.n_actions, pairs.col
        chunk = max(1, MOVE_ELEMENTS // features.shape[1])
        for lo in range(0, len(sources), chunk):  # (moves, F) a chunk at a time
            step = features[targets[lo : lo + chunk]] - features[sources[lo : lo + chunk]]
            change = np.maximum(change, np.abs(step).max(axis=0, initial=0.0))
    narrow = (span > 0) & (span < 1.0 - MOVE_UNIT_SLACK)
    scale = np.where(change > 1.0 + MOVE_UNIT_SLACK, change, np.where(narrow, span, 1.0))
    if (scale == 1.0).all() and (low == 0).all():
        return features
    out = features - low.astype(features.dtype)  # one copy, in the features' own float32
    out /= scale  # divided in float64 element by element, rounded once into the copy
    return out


def initial_input_scale(inputs: torch.Tensor) -> torch.Tensor | None:
    """Per input column of ``inputs`` (S, F), min(1, 1 / its root mean square over the states): the factor of
    that column's initial first-layer weights. None when no column's root mean square exceeds 1.

    nn.Linear's initialisation, U(−1/√fan_in, 1/√fan_in), is made for inputs of about unit size. Distances of
    up to twenty cells (objectworld, after `input_units`) then start every column with a contribution several
    times that: the initial reward varies along every column, and the few demonstrations must undo it along the
    columns that do not matter. Started at unit size, each column's weights grow only as far as the
    demonstrations push them. On the four-colour objectworld, six of whose eight distance columns do not enter
    the reward, the default's Pearson at 3 demonstrations went from 0.271 to 0.341 (worlds 0–5; the two
    relevant columns alone gave 0.539 on worlds 0–2), on the two-colour family from 0.511 to 0.552
    (docs/method.md, "Feature units"). Coordinates, indicators and other inputs within ±1 keep the default.
    """
    rms = torch.linalg.vector_norm(inputs, dim=0) / inputs.shape[0] ** 0.5
    if not bool((rms > 1).any()):
        return None
    return torch.where(rms > 1, 1 / rms, torch.ones_like(rms))


def place_inputs(features: np.ndarray, tasks: Sequence[TaskData], config: FitConfig) -> np.ndarray | None:
    """The place the task networks see besides the MDP's ``features`` (in input units): the states'
    coordinates and their waves at COORDINATE_OCTAVES octaves, when `FitConfig.task_coordinates` asks for
    them, the MDP has features of its own and no feature column already is one of them; else None."""
    mdps = [t.mdp for t in tasks]
    if mdps[0].features is None or not config.task_coordinates:
        return None  # coordinates standing in for missing features, or not asked for
    coordinates = state_coordinates(mdps, seed=config.seed)
    if coordinates is None or all(any(np.array_equal(c, f) for f in features.T) for c in coordinates.T):
        return None
    return fourier_features(coordinates, octaves=COORDINATE_OCTAVES)


def _joined(features: np.ndarray, place: np.ndarray) -> np.ndarray:
    """The features followed by the place's columns, float32."""
    return np.concatenate([features, place], axis=1).astype(np.float32)


def _baseline_columns(config: FitConfig, features: np.ndarray | None) -> list[int] | None:
    """The feature columns the baseline network sees (`FitConfig.baseline_features`); None: all."""
    check(baseline_column_issues(config, n_columns=None if features is None else features.shape[1]))
    if config.baseline_features is None:
        return None
    return list(config.baseline_features)


def _stack_members(parts: Sequence[Steps], n_tasks: int) -> Steps:
    """One `Steps` of T·K networks from K members' steps of T tasks (member k's task i is network k·T + i)."""
    return Steps(
        np.concatenate([p.tasks + k * n_tasks for k, p in enumerate(parts)]),
        np.concatenate([p.states for p in parts]),
        np.concatenate([p.actions for p in parts]),
    )


def per_task_nll(
    q: torch.Tensor, actions: torch.Tensor, tasks: torch.Tensor, *, n_tasks: int, confidence: float
) -> torch.Tensor:
    """Mean NLL (T,) of demonstrated actions under softmax(b·Q) per task (paper eq. 10, averaged)."""
    nll = F.cross_entropy(confidence * q, actions, reduction="none")
    count = segment_sum(torch.ones_like(nll), tasks, n_tasks).clamp_min(1.0)
    return segment_sum(nll, tasks, n_tasks) / count


TEMPERATURES = torch.logspace(-2, 2, 17, base=2.0)
"""Scales t of Q (¼ … 4, 17 steps) over which the held-out NLL is calibrated (see `calibrated_nll`)."""


def calibrated_nll(
    q: torch.Tensor, actions: torch.Tensor, *, confidence: float, groups: Sequence[torch.Tensor]
) -> list[torch.Tensor]:
    """Per group of held-out rows, their NLLs under softmax(t·b·Q) at the t in TEMPERATURES best for the group.

    The VR networks fix the scale of Q only through the fixed confidence b, and that scale keeps growing
    while the ranking of actions — what the reward says — is still improving: the plain held-out NLL then
    rises because the policy is over-confident, not because the reward got worse (on velocity grids it
    stopped fits at step 5-60 whose reward kept improving for hundreds of steps; benchmarks/stopping.py).
    Scoring each step at its best temperature judges the reward's ranking of actions, not its scale.
    """
    scaled = TEMPERATURES.to(q.device)[:, None, None] * (confidence * q)  # (len(TEMPERATURES), N, A)
    picked = actions.expand(len(TEMPERATURES), -1).unsqueeze(-1)  # each row's demonstrated action
    nll = -torch.log_softmax(scaled, dim=-1).gather(2, picked).squeeze(-1)  # (len(TEMPERATURES), N)
    return [nll[nll[:, rows].mean(dim=1).argmin(), rows] for rows in groups]


class HeldOutStopper:
    """Early stopping on held-out NLL with the one-standard-error rule (Hastie et al., ESL §7.10).

    The estimate the paper asks for is the optimum of eq. 1, so training runs as long as the held-out NLL
    stays statistically indistinguishable from its best: a step is *kept* when its held-out NLL is within
    one standard error (of the per-step NLLs at the best step) of the best so far. The fit stops once the
    held-out NLL has made no *meaningful* progress for ``patience`` steps: no step has beaten the level of
    the last progress by more than that level's standard error. Smaller new bests are within the NLL's
    own sampling noise: on large grids it creeps down by such amounts for hundreds of steps while the
    rewards stop changing what they say about the held-out actions (benchmarks/RESULTS.md, "When to stop").
    Either way the NLL has climbed away (without sharing a few demonstrations are overfit fast) or
    plateaued, and further steps only cost time.
    """

    def __init__(self, *, patience: int):
        self.patience = patience
        self.best, self.tolerance, self.kept_step = float("inf"), 0.0, 0
        self.level, self.level_tolerance, self.progress_step = float("inf"), 0.0, 0

    def update(self, step: int, per_step_nll: torch.Tensor) -> bool:
        """Record this step's held-out NLLs (one per held-out demonstrated step); True if the step is kept."""
        mean = float(per_step_nll.mean())
        n = per_step_nll.numel()
        standard_error = float(per_step_nll.std()) / n**0.5 if n > 1 else 0.0
        if mean < self.best:
            self.best, self.tolerance = mean, standard_error
        if mean < self.level - self.level_tolerance:  # meaningful progress: the patience starts again
            self.level, self.level_tolerance, self.progress_step = mean, standard_error, step
        if mean <= self.best + self.tolerance:
            self.kept_step = step
            return True
        return False

    def should_stop(self, step: int) -> bool:
        """True once ``patience`` steps have passed without meaningful progress (never when patience is 0)."""
        return self.patience > 0 and step - self.progress_step >= self.patience


def objective(
    problem: _Problem, block: _Block, f: torch.Tensor, r_b: torch.Tensor | None, config: FitConfig
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The training loss from the network outputs: (loss, IRL loss (T,), sharing loss (T,)).

    ``f`` (T·K, |U|) are the VR values f_i(s) = r_i(s) + γ V_i(s) (eq. 5) on the block's states U, ``r_b``
    (K, B) the members' baseline rewards on ``block.base_states`` (None without sharing). The sharing loss
    is a mean over the block's states: over a random block, an unbiased estimate of the mean over all.
    """
    n_tasks = problem.n_nets
    irl = per_task_nll(  # NLL of demonstrated actions under softmax(b·Q)                 eq. 6, 10
        block.q_train(f),
        problem.train_actions,
        problem.train_tasks,
        n_tasks=n_tasks,
        confidence=config.confidence,
    )
    shared = torch.zeros(n_tasks, dtype=f.dtype, device=f.device)
    if r_b is not None:
        v = backup(block.q_share(f), kind=config.backup, bgi_k=config.bgi_k)  # V_i(s)       eq. 7
        r = f.reshape(-1).index_select(0, block.share_f) - block.share_gamma * v  # r_i      eq. 8
        base = r_b.reshape(-1).index_select(0, block.share_base)
        if block.share_weight is not None:  # same values; r_b's gradient per row times its weight
            weight = block.share_weight.to(base.dtype)
            base = weight * base + (1.0 - weight) * base.detach()
        diff = r - base
        shared = sharing_loss(diff, block.share_tasks, n_tasks=n_tasks, kind=config.sharing)
    loss = (irl + config.sharing_weight * shared).mean()  # eq. 1, averaged over tasks
    return loss, irl, shared


def gradient_step(
    problem: _Problem,
    vr: StackedMLP,
    base: StackedMLP,
    config: FitConfig,
    *,
    block: int = 0,
    chunk: int = TRAIN_CHUNK,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Accumulate the loss gradient on sharing block ``block`` in the networks' ``.grad``; returns (loss,
    irl, sharing, f detached on the block's states U).

    With more than ``chunk`` states the networks run twice, checkpoint style: once without autograd to get
    f and r_b, whose gradients the loss gives; then chunk by chunk with autograd, back-propagating those
    gradients. Same gradient, activation memory bounded by the chunk instead of T × |U| × width.
    """
    rows = problem.blocks[block]
    sharing_on = config.sharing != "none"
    n_u = rows.states_u.shape[1]
    n_b = len(rows.base_states) if sharing_on else 0
    if max(n_u, n_b) <= chunk:
        f = vr(rows.inputs_u)
        r_b = base(rows.inputs_base) if sharing_on else None
        loss, irl, shared = objective(problem, rows, f, r_b, config)
        loss.backward()
        return loss.detach(), irl.detach(), shared.detach(), f.detach()
    with torch.no_grad():
        f = torch.cat([vr(rows.inputs_u[:, i : i + chunk]) for i in range(0, n_u, chunk)], dim=1)
        r_b = (
            torch.cat([base(rows.inputs_base[i : i + chunk]) for i in range(0, n_b, chunk)], dim=1)
            if n_b
            else None
        )
    f.requires_grad_(True)
    if r_b is not None:
        r_b.requires_grad_(True)
    loss, irl, shared = objective(problem, rows, f, r_b, config)
    loss.backward()
    assert f.grad is not None
    for i in range(0, n_u, chunk):
        vr(rows.inputs_u[:, i : i + chunk]).backward(f.grad[:, i : i + chunk])
    if r_b is not None:
        assert r_b.grad is not None
        for i in range(0, n_b, chunk):
            base(rows.inputs_base[i : i + chunk]).backward(r_b.grad[:, i : i + chunk])
    return loss.detach(), irl.detach(), shared.detach(), f.detach()


def _fit_meta_irl(
    tasks: Sequence[TaskData],
    config: FitConfig,
    *,
    progress: ProgressCallback | None,
    should_stop: StopCheck | None,
    device: torch.device,
) -> tuple[FitResult, torch.Tensor | None]:
    """The paper's method: joint Adam on all VR networks and the baseline network (Algorithm 1); with the
    result, its K-fold held-out NLL per held-out step (`_heldout_score`; None without a hold-out).

    With an ensemble the K members train side by side in the same batched ops; Adam's update is elementwise,
    so each member follows exactly the path it would follow alone. The members are the K folds of a
    cross-validation: the step kept, and when to stop, is judged by all their held-out folds together.
    """
    started = time.perf_counter()
    problem = _Problem(tasks, config).to(device)
    generator = torch.Generator().manual_seed(config.seed)
    n_inputs = problem.n_states if problem.features is None else problem.features.shape[1]
    tabular = problem.features is None
    vr = StackedMLP(
        n_members=problem.n_nets,
        n_inputs=n_inputs,
        hidden=config.hidden,
        tabular=tabular,
        generator=generator,
        input_scale=None if problem.features is None else initial_input_scale(problem.features),
    ).to(device)
    base_inputs = n_inputs if problem.base_features is None else problem.base_features.shape[1]
    base = StackedMLP(
        n_members=problem.n_members,
        n_inputs=base_inputs,
        hidden=config.hidden,
        tabular=tabular,
        generator=generator,
        input_scale=None if problem.base_features is None else initial_input_scale(problem.base_features),
    ).to(device)
    params = [*vr.parameters(), *base.parameters()]
    # fused: one kernel per step for every parameter (a third of foreach's time on a 576-state ensemble step)
    optimiser = torch.optim.Adam(params, lr=config.learning_rate, fused=True)

    history: list[Progress] = []
    # The K members are the K folds of a cross-validation: one stopper judges the step by every member's
    # held-out NLL on its own fold, and all members keep the same step.
    stopper = HeldOutStopper(patience=config.patience)
    kept = [p.detach().clone() for p in params]
    previous_loss: float | None = None
    flat_steps = 0  # consecutive steps whose loss change was within the tolerance
    for step in range(1, config.max_steps + 1):
        if should_stop is not None and should_stop():
            raise Cancelled(f"fit cancelled at step {step}")
        optimiser.zero_grad(set_to_none=True)
        block = (step - 1) % len(problem.blocks)  # the sharing blocks in turn
        loss, irl, shared, f = gradient_step(problem, vr, base, config, block=block)
        if not math.isfinite(float(loss)):  # NaN or inf poisons every later step and the step kept
            raise Diverged(
                f"The fit diverged at step {step}: its loss became {float(loss)}. Lower config.confidence "
                f"({config.confidence:g}), config.learning_rate ({config.learning_rate:g}) or "
                f"config.sharing_weight ({config.sharing_weight:g})."
            )

        held_nll: float | None = None
        if len(problem.held):
            with torch.no_grad():
                q_held = problem.blocks[block].q_held(f)
                held_nll = float(F.cross_entropy(config.confidence * q_held, problem.held_actions))
                folds = calibrated_nll(
                    q_held, problem.held_actions, confidence=config.confidence, groups=problem.held_of_member
                )
                if stopper.update(step, torch.cat(folds)):
                    for copy, live in zip(kept, params, strict=True):
                        copy.copy_(live)

        optimiser.step()

        record = Progress(
            step=step,
            max_steps=config.max_steps,
            loss=float(loss),
            irl_loss=float(irl.mean()),
            sharing_loss=float(shared.mean()),
            heldout_nll=held_nll,
            elapsed_s=time.perf_counter() - started,
        )
        history.append(record)
        if progress is not None:
            progress(record)
        if held_nll is not None and stopper.should_stop(step):
            break
        flat = previous_loss is not None and abs(record.loss - previous_loss) <= config.tolerance * max(
            abs(previous_loss), 1e-12
        )
        flat_steps = flat_steps + 1 if flat else 0
        if flat_steps >= CONVERGED_STEPS:
            break
        previous_loss = record.loss

    if len(problem.held):
        with torch.no_grad():
            for copy, live in zip(kept, params, strict=True):
                live.copy_(copy)
    best_step = stopper.kept_step if len(problem.held) else len(history)
    return _evaluate(problem, vr, base, config, history=history, best_step=best_step)


def _evaluate(
    problem: _Problem,
    vr: StackedMLP,
    base: StackedMLP,
    config: FitConfig,
    *,
    history: list[Progress],
    best_step: int,
) -> tuple[FitResult, torch.Tensor | None]:
    """Rewards, values and policies of every task on every state from the kept networks (eq. 5–9), and
    their K-fold held-out NLL per held-out step (None without a hold-out).

    With sharing and a hold-out, each member's task rewards are first shrunk towards its baseline by the λ and
    made sparse by the q its held-out folds choose (`shrinkage.shrink_deviations`; values and policies are then those of the
    shrunk rewards). With an ensemble, each quantity is the mean over the K members (policies: the members'
    mixture), and the rewards' spread across the members comes with them (`member_spread`).
    """
    all_states = np.arange(problem.n_states)
    n_members, n_tasks, n_states = problem.n_members, problem.n_tasks, problem.n_states
    with torch.no_grad():
        chunks = [problem.inputs(all_states[i : i + EVAL_CHUNK]) for i in range(0, n_states, EVAL_CHUNK)]
        f = torch.cat([vr(c) for c in chunks], dim=1)  # (T·K, S)
        # Without sharing the baseline network is never trained: report the mean task reward instead.
        base_members = (
            torch.cat(
                [
                    base(problem.inputs(all_states[i : i + EVAL_CHUNK], base=True))
                    for i in range(0, n_states, EVAL_CHUNK)
                ],
                dim=1,
            )
            if config.sharing != "none"
            else None
        )
        nets = np.repeat(np.arange(problem.n_nets), n_states)
        every_row = QRows(
            problem.mdps, nets, np.tile(all_states, problem.n_nets), columns=all_states, n_columns=n_states
        ).to(problem.device)
        q_all = every_row(f).reshape(problem.n_nets, n_states, -1)
        values = backup(q_all, kind=config.backup, bgi_k=config.bgi_k)
        members = (f - problem.gamma[:, None] * values).reshape(n_members, n_tasks, n_states)
        shrinkage, sparsity = 1.0, 0.0
        if (
            base_members is not None
            and config.shrink_deviations
            and len(problem.held)
            and problem.n_nets * n_states <= SHRINK_BUDGET
        ):
            shrunk = shrink_deviations(
                every_row,
                members.reshape(problem.n_nets, n_states),
                base_members.repeat_interleave(n_tasks, dim=0),  # network k·T + i: member k's baseline
                problem.gamma,
                q=q_all,
                values=values,
                score=lambda q: _heldout_score(problem, q, config),
                kind=config.backup,
                bgi_k=config.bgi_k,
            )
            shrinkage, sparsity, q_all, values = shrunk.shrinkage, shrunk.sparsity, shrunk.q, shrunk.values
            members = shrunk.rewards.reshape(n_members, n_tasks, n_states)
        rewards = members.mean(dim=0)
        if base_members is None:
            base_members = members.mean(dim=1)
        values = values.reshape(n_members, n_tasks, n_states).mean(dim=0)
        policies = torch.softmax(config.confidence * q_all, dim=-1)
        policies = policies.reshape(n_members, n_tasks, n_states, -1).mean(dim=0)
        score = _heldout_score(problem, q_all, config) if len(problem.held) else None
    result = FitResult(
        baseline=base_members.mean(dim=0).cpu().numpy().astype(np.float32),
        rewards=rewards.cpu().numpy().astype(np.float32),
        values=values.cpu().numpy().astype(np.float32),
        policies=policies.cpu().numpy().astype(np.float32),
        history=history,
        best_step=best_step,
        config=replace(config, ensemble=n_members),  # an automatic ensemble's K stated: a refit fits as many
        baseline_spread=member_spread(base_members),
        reward_spread=member_spread(members),
        shrinkage=shrinkage,
        sparsity=sparsity,
    )
    return result, score


def _heldout_score(problem: _Problem, q: torch.Tensor, config: FitConfig) -> torch.Tensor:
    """The K-fold held-out NLL of Q (T·K, S, A) per held-out step: each member's held-out steps, calibrated
    over the scale of Q per member as the stopping rule scores them (`calibrated_nll`)."""
    held = problem.held
    tasks = torch.from_numpy(held.tasks).to(q.device)
    states = torch.from_numpy(held.states).to(q.device)
    folds = calibrated_nll(
        q[tasks, states], problem.held_actions, confidence=config.confidence, groups=problem.held_of_member
    )
    return torch.cat(folds)


def member_spread(members: torch.Tensor) -> np.ndarray | None:
    """Per state, the standard deviation across the ensemble's K members (dim 0) of their rewards, each put
    on the ensemble mean's scale first by a least-squares affine fit over the states (a reward's level and
    scale are not identified, so members that differ only so agree); float32 of shape ``members.shape[1:]``,
    None with K = 1. What it estimates is the variability of a fit, not its error (`FitResult`)."""
    if members.shape[0] < 2:
        return None
    centred = members - members.mean(dim=-1, keepdim=True)
    mean = centred.mean(dim=0, keepdim=True)
    slope = (centred * mean).sum(dim=-1, keepdim=True) / (centred**2).sum(dim=-1, keepdim=True).clamp_min(
        1e-12
    )
    return (slope * centred).std(dim=0).cpu().numpy().astype(np.float32)


class _CallableModule(types.ModuleType):
    """This module, callable as its `fit`: the package exports the function `fit` under the module's own name,
    and Python binds that name to the module once the module is imported, so either way
    ``from metairl_engine import fit; fit(tasks, config)`` runs the fit."""

    def __call__(
        self,
        tasks: Sequence[TaskData],
        config: FitConfig = FitConfig(),
        **options: Any,
    ) -> FitResult:
        return fit(tasks, config, **options)


sys.modules[__name__].__class__ = _CallableModule
