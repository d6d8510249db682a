"""Reference solvers: tabular maximum-causal-entropy IRL (numpy/scipy, no networks), each task alone or all
tasks around one shared reward.

For each task, find the state reward r (S,) maximising the likelihood of the demonstrated actions under
the soft-optimal policy π = softmax(b·Q) with Q(s, a) = Σ_s' P(s'|s, a)[r(s') + γV(s')] and
V = (1/b) log Σ_a exp(b·Q) (Ziebart et al. 2010), by L-BFGS with the exact gradient:

    ∂/∂r Σ log π(a|s) = b · c (I − γ P_π)⁻¹,   c = Σ_(s,a) [P(·|s, a) − P_π(·|s)]

(differentiate Q = P(r + γV) and V = Σ_a π Q; the inverse is applied by fixed-point iteration, no solve).
A small ridge ``RIDGE/2·‖r‖²`` makes unvisited states' rewards 0 instead of undetermined.

``method="maxent"`` solves each task alone; its ``baseline`` is the mean of the task rewards (it learns none).
``method="shared_maxent"`` is reward sharing in the tabular solver: every task's reward is one shared reward
r_b plus, at the final states of the task's demonstrations that `ended_by_choice`, a bonus of its own,

    r_i = r_b + Σ_e u_(i,e)·1[s = e],   minimise Σ_i NLL_i(r_i)/N_i + RIDGE/2·‖r_b‖² + BONUS_RIDGE/2·‖u‖²,

so a state any task's demonstrations pass gets its reward from all of them, and only where a demonstration
stopped because it was done (its goal) may a task's reward depart from the others'. The ``baseline`` is r_b.
A stop says where the task itself wants to be, so its bonus carries the goal (`BONUS_RIDGE`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize

from metairl_engine.config import FitConfig
from metairl_engine.demos import chosen_ends, state_action_pairs, with_stays_at_ends
from metairl_engine.errors import Cancelled
from metairl_engine.mdp import MDP
from metairl_engine.planning import policy_matrix, stay_actions, transition_matrix, value_iteration
from metairl_engine.results import FitResult, Progress, TaskData

RIDGE = 1e-3
"""Weight of the ridge penalty on the tabular reward (per state, relative to the mean NLL per step)."""

BONUS_RIDGE = RIDGE / 100
"""Ridge on ``shared_maxent``'s bonuses u. At a task's goal only r_b + u is evidenced, and a MAP splits it in
proportion to the priors' variances: equal ridges would put half of every goal into the shared reward, where
every other task's policy is drawn to it (docs/method.md, "The tabular solvers"); a prior 100 times wider on
the bonuses leaves the shared reward about 1 % of a goal."""


def fit_maxent(
    tasks: Sequence[TaskData],
    config: FitConfig,
    *,
    progress: Callable[[Progress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> FitResult:
    """Solve each task alone (``maxent``) or all around a shared reward (``shared_maxent``); steps in
    `Progress` count L-BFGS iterations over all tasks."""
    matrices: dict[int, tuple[sp.csr_matrix, np.ndarray | None]] = {}
    stays = config.method == "shared_maxent" and config.stay_at_ends

    def objective_of(task: TaskData) -> _TaskObjective:
        """The task's objective, on one transition matrix per distinct MDP; ``shared_maxent`` with
        `FitConfig.stay_at_ends` also counts the stay at each final state a demonstration ended at by choice."""
        if id(task.mdp) not in matrices:
            matrices[id(task.mdp)] = transition_matrix(task.mdp), stay_actions(task.mdp) if stays else None
        p, stay = matrices[id(task.mdp)]
        if stay is not None:
            task = replace(task, trajectories=with_stays_at_ends(task.trajectories, stay))
        return _TaskObjective(task, p, config, should_stop=should_stop)

    objectives = [objective_of(t) for t in tasks]
    if config.method == "shared_maxent":
        reporter = _Reporter(config.max_steps, progress)
        shared = _SharedObjective(tasks, objectives)
        baseline, rewards = shared.rewards(reporter.minimize(shared, shared.start(), config))
    else:
        reporter = _Reporter(config.max_steps * len(tasks), progress)
        rewards = np.asarray([reporter.minimize(o, np.zeros(o.mdp.n_states), config) for o in objectives])
        baseline = rewards.astype(np.float32).mean(axis=0)
    plans = [
        value_iteration(o.p, r, gamma=o.mdp.gamma, confidence=config.confidence)
        for o, r in zip(objectives, rewards, strict=True)
    ]
    return FitResult(
        baseline=np.asarray(baseline, dtype=np.float32),
        rewards=np.asarray(rewards, dtype=np.float32),
        values=np.asarray([plan.value for plan in plans], dtype=np.float32),
        policies=np.asarray([plan.policy for plan in plans], dtype=np.float32),
        history=reporter.history,
        best_step=len(reporter.history),
        config=config,
    )


class _Reporter:
    """Runs L-BFGS on an objective and records each iteration as `Progress` out of ``total_steps``."""

    def __init__(self, total_steps: int, progress: Callable[[Progress], None] | None):
        self.total_steps, self.progress = total_steps, progress
        self.history: list[Progress] = []
        self.started = time.perf_counter()

    def minimize(
        self, objective: _TaskObjective | _SharedObjective, start: np.ndarray, config: FitConfig
    ) -> np.ndarray:
        """The minimiser of ``objective`` from ``start`` (at most ``config.max_steps`` iterations)."""

        def report(_: np.ndarray) -> None:
            """Record one L-BFGS iteration."""
            record = Progress(
                step=len(self.history) + 1,
                max_steps=self.total_steps,
                loss=objective.loss,
                irl_loss=objective.nll,
                sharing_loss=0.0,
                heldout_nll=None,
                elapsed_s=time.perf_counter() - self.started,
            )
            self.history.append(record)
            if self.progress is not None:
                self.progress(record)

        solution = minimize(
            objective,
            start,
            jac=True,
            method="L-BFGS-B",
            callback=report,
            options={"maxiter": config.max_steps, "ftol": config.tolerance, "gtol": 1e-8},
        )
        return np.asarray(solution.x)


class _TaskObjective:
    """Mean NLL + ridge of one task's demonstrations and its gradient, as a function of the reward (S,)."""

    def __init__(
        self, task: TaskData, p: sp.csr_matrix, config: FitConfig, *, should_stop: Callable[[], bool] | None
    ):
        self.mdp: MDP = task.mdp
        self.p, self.config, self.should_stop = p, config, should_stop
        self.states, self.actions = state_action_pairs(task.trajectories)
        n_sa = np.bincount(self.states * self.mdp.n_actions + self.actions, minlength=self.p.shape[0])
        self.n_s = np.bincount(self.states, minlength=self.mdp.n_states).astype(np.float64)
        self.demanded = self.p.T @ n_sa.astype(np.float64)  # Σ_(s,a) P(·|s, a)
        self.value = np.zeros(self.mdp.n_states)  # warm start of soft value iteration
        self.loss = self.nll = 0.0

    def __call__(self, r: np.ndarray) -> tuple[float, np.ndarray]:
        """(objective, gradient) at reward r."""
        nll, gradient = self.likelihood(r)
        self.loss = nll + 0.5 * RIDGE * float(r @ r)
        return self.loss, gradient + RIDGE * r

    def likelihood(self, r: np.ndarray) -> tuple[float, np.ndarray]:
        """(mean NLL per demonstrated step, its gradient) at reward r; checks for cancellation first."""
        self.check_cancelled()
        plan = value_iteration(
            self.p, r, gamma=self.mdp.gamma, confidence=self.config.confidence, initial_value=self.value
        )
        return self.planned(plan.value, plan.policy)

    def check_cancelled(self) -> None:
        """Raise `Cancelled` once the fit has been asked to stop."""
        if self.should_stop is not None and self.should_stop():
            raise Cancelled("fit cancelled")

    def planned(self, value: np.ndarray, policy: np.ndarray) -> tuple[float, np.ndarray]:
        """(mean NLL per demonstrated step, its gradient) given the soft plan of the reward: its value (S,),
        kept as the next plan's warm start, and its policy (S, A)."""
        self.value = value
        self.nll = -float(np.mean(np.log(np.maximum(policy[self.states, self.actions], 1e-300))))
        p_pi = policy_matrix(self.p, policy)
        x = _discounted_solve(p_pi, self.demanded - p_pi.T @ self.n_s, gamma=self.mdp.gamma)
        return self.nll, -self.config.confidence * x / len(self.states)


class _SharedObjective:
    """Σ_i mean NLL_i + ridges of ``shared_maxent`` and its gradient, as a function of x = (r_b (S,), u (K,)):
    the shared reward and the K bonuses, one per task and final state its demonstrations ended at by choice."""

    def __init__(self, tasks: Sequence[TaskData], objectives: Sequence[_TaskObjective]):
        self.objectives = objectives
        self.n_states = tasks[0].mdp.n_states
        ends = [chosen_ends(t.trajectories) for t in tasks]
        self.bonus_task = np.repeat(np.arange(len(tasks)), [len(e) for e in ends])
        self.bonus_state = np.concatenate(ends)
        self.ridge = np.concatenate(
            [np.full(self.n_states, RIDGE), np.full(len(self.bonus_state), BONUS_RIDGE)]
        )
        self.loss = self.nll = 0.0

    def start(self) -> np.ndarray:
        """All rewards 0."""
        return np.zeros(self.n_states + len(self.bonus_state))

    def rewards(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The shared reward (S,) and the task rewards (T, S) at x."""
        baseline, bonus = x[: self.n_states], x[self.n_states :]
        rewards = np.repeat(baseline[None], len(self.objectives), axis=0)
        np.add.at(rewards, (self.bonus_task, self.bonus_state), bonus)
        return baseline, rewards

    def __call__(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """(objective, gradient) at x."""
        _, rewards = self.rewards(x)
        terms = self.likelihoods(rewards)
        gradients = np.asarray([g for _, g in terms])
        self.nll = float(sum(nll for nll, _ in terms))  # summed over the tasks
        self.loss = self.nll + 0.5 * float(self.ridge @ (x * x))
        gradient = np.concatenate([gradients.sum(axis=0), gradients[self.bonus_task, self.bonus_state]])
        return self.loss, gradient + self.ridge * x

    def likelihoods(self, rewards: np.ndarray) -> list[tuple[float, np.ndarray]]:
        """Each task's (mean NLL, gradient) at its reward (rewards (T, S)); the tasks on one MDP are planned
        together (`value_iteration` of a batch: one sparse product per iteration for all of them)."""
        self.objectives[0].check_cancelled()
        terms: dict[int, tuple[float, np.ndarray]] = {}
        for tasks in _by_transitions(self.objectives).values():
            first = self.objectives[tasks[0]]
            plan = value_iteration(
                first.p,
                rewards[tasks].T,
                gamma=first.mdp.gamma,
                confidence=first.config.confidence,
                initial_value=np.stack([self.objectives[i].value for i in tasks], axis=1),
            )
            for k, i in enumerate(tasks):
                terms[i] = self.objectives[i].planned(plan.value[:, k], plan.policy[:, :, k])
        return [terms[i] for i in range(len(self.objectives))]


def _by_transitions(objectives: Sequence[_TaskObjective]) -> dict[int, list[int]]:
    """The objectives' indices grouped by their MDP's transition matrix (one per distinct MDP)."""
    groups: dict[int, list[int]] = {}
    for i, o in enumerate(objectives):
        groups.setdefault(id(o.p), []).append(i)
    return groups


def _discounted_solve(
    p_pi: sp.csr_matrix, c: np.ndarray, *, gamma: float, tolerance: float = 1e-10
) -> np.ndarray:
    """x = c (I − γ P_π)⁻¹ as a column: iterate x ← c + γ P_πᵀ x (a γ-contraction)."""
    p_t = sp.csr_matrix(p_pi.T)
    x = c.copy()
    scale = max(float(np.max(np.abs(c))), 1e-300)
    for _ in range(100_000):
        new_x = c + gamma * (p_t @ x)
        if float(np.max(np.abs(new_x - x))) <= tolerance * scale:
            return np.asarray(new_x)
        x = new_x
    return np.asarray(x)
