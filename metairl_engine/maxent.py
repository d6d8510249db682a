"""Reference solver: tabular maximum-causal-entropy IRL, one task at a time (numpy/scipy, no networks).

For each task, find the state reward r (S,) maximising the likelihood of the demonstrated actions under
the soft-optimal policy π = softmax(b·Q) with Q(s, a) = Σ_s' P(s'|s, a)[r(s') + γV(s')] and
V = (1/b) log Σ_a exp(b·Q) (Ziebart et al. 2010), by L-BFGS with the exact gradient:

    ∂/∂r Σ log π(a|s) = b · c (I − γ P_π)⁻¹,   c = Σ_(s,a) [P(·|s, a) − P_π(·|s)]

(differentiate Q = P(r + γV) and V = Σ_a π Q; the inverse is applied by fixed-point iteration, no solve).
A small ridge ``RIDGE/2·‖r‖²`` makes unvisited states' rewards 0 instead of undetermined.
The result has FitResult's shape; its ``baseline`` is the mean of the task rewards (this solver has none).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize

from metairl_engine.config import FitConfig
from metairl_engine.demos import state_action_pairs
from metairl_engine.errors import Cancelled
from metairl_engine.planning import policy_matrix, transition_matrix, value_iteration
from metairl_engine.results import FitResult, Progress, TaskData

RIDGE = 1e-3
"""Weight of the ridge penalty on the tabular reward (per state, relative to the mean NLL per step)."""


def fit_maxent(
    tasks: Sequence[TaskData],
    config: FitConfig,
    *,
    progress: Callable[[Progress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> FitResult:
    """Solve each task independently; steps in `Progress` count L-BFGS iterations over all tasks."""
    started = time.perf_counter()
    history: list[Progress] = []
    total_steps = config.max_steps * len(tasks)
    rewards, values, policies = [], [], []
    for task in tasks:
        mdp = task.mdp
        p = transition_matrix(mdp)
        objective = _TaskObjective(task, config, should_stop=should_stop)

        def report(_: np.ndarray, objective: _TaskObjective = objective) -> None:
            """Record one L-BFGS iteration."""
            record = Progress(
                step=len(history) + 1,
                max_steps=total_steps,
                loss=objective.loss,
                irl_loss=objective.nll,
                sharing_loss=0.0,
                heldout_nll=None,
                elapsed_s=time.perf_counter() - started,
            )
            history.append(record)
            if progress is not None:
                progress(record)

        solution = minimize(
            objective,
            np.zeros(mdp.n_states),
            jac=True,
            method="L-BFGS-B",
            callback=report,
            options={"maxiter": config.max_steps, "ftol": config.tolerance, "gtol": 1e-8},
        )
        r = solution.x
        plan = value_iteration(p, r, gamma=mdp.gamma, confidence=config.confidence)
        rewards.append(r)
        values.append(plan.value)
        policies.append(plan.policy)
    reward_arr = np.asarray(rewards, dtype=np.float32)
    return FitResult(
        baseline=reward_arr.mean(axis=0),
        rewards=reward_arr,
        values=np.asarray(values, dtype=np.float32),
        policies=np.asarray(policies, dtype=np.float32),
        history=history,
        best_step=len(history),
        config=config,
    )


class _TaskObjective:
    """Mean NLL + ridge of one task's demonstrations and its gradient, as a function of the reward (S,)."""

    def __init__(self, task: TaskData, config: FitConfig, *, should_stop: Callable[[], bool] | None):
        self.mdp, self.config, self.should_stop = task.mdp, config, should_stop
        self.p = transition_matrix(task.mdp)
        self.states, self.actions = state_action_pairs(task.trajectories)
        n_sa = np.bincount(self.states * self.mdp.n_actions + self.actions, minlength=self.p.shape[0])
        self.n_s = np.bincount(self.states, minlength=self.mdp.n_states).astype(np.float64)
        self.demanded = self.p.T @ n_sa.astype(np.float64)  # Σ_(s,a) P(·|s, a)
        self.value = np.zeros(self.mdp.n_states)  # warm start of soft value iteration
        self.loss = self.nll = 0.0

    def __call__(self, r: np.ndarray) -> tuple[float, np.ndarray]:
        """(objective, gradient) at reward r; checks for cancellation first."""
        if self.should_stop is not None and self.should_stop():
            raise Cancelled("fit cancelled")
        b = self.config.confidence
        plan = value_iteration(self.p, r, gamma=self.mdp.gamma, confidence=b, initial_value=self.value)
        self.value = plan.value
        self.nll = -float(np.mean(np.log(np.maximum(plan.policy[self.states, self.actions], 1e-300))))
        p_pi = policy_matrix(self.p, plan.policy)
        x = _discounted_solve(p_pi, self.demanded - p_pi.T @ self.n_s, gamma=self.mdp.gamma)
        self.loss = self.nll + 0.5 * RIDGE * float(r @ r)
        return self.loss, -b * x / len(self.states) + RIDGE * r


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
