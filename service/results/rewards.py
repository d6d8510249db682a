"""A job's reward rows: written by the worker (`add_reward`), looked up in the caller's lab with what names and
draws them (`RewardContext`), and listed with their summaries and truth scores (docs/api.md, "Rewards")."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_engine.mdp import Layout
from metairl_engine.motion.readout import BASELINE_CAVEAT

if TYPE_CHECKING:
    pass

from service.domain.comparisons import (
    ComparedSide,
)
from service.domain.rewards import (
    JobRewards,
    Quantity,
    RewardRef,
    RewardSummary,
    reward_links,
)
from service.files import exports
from service.problems import Conflict
from service.results.engine_modules import metrics
from service.store.blobs import get_array, put_array
from service.store.ids import new_id
from service.store.loaders import load_true_reward
from service.store.models.demonstrators import Demonstrator, Task
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, Reward
from service.store.models.mdps import Mdp
from service.store.owned import get_owned


@dataclass(frozen=True)
class RewardContext:
    """A reward row with what names and draws it: job, task (None for the baseline), demonstrator, layout."""

    row: Reward
    job: Job
    task: Task | None
    demonstrator: Demonstrator
    mdp: Mdp

    @property
    def layout(self) -> Layout | None:
        """How the states tile a picture, if the MDP has a layout."""
        return Layout(**self.mdp.layout) if self.mdp.layout else None

    @property
    def task_ids(self) -> list[str]:
        """The tasks whose demonstrations are behind this reward: its task, or every task of the job."""
        return [self.task.id] if self.task else list(self.job.task_ids)

    @property
    def label(self) -> str:
        """``task — demonstrator``, or ``baseline — demonstrator``."""
        return f"{self.task.name if self.task else 'baseline'} — {self.demonstrator.name}"

    def describe(self) -> ComparedSide:
        """This reward as one side of a comparison."""
        return ComparedSide(
            kind="reward",
            label=self.label,
            reward_id=self.row.id,
            job_id=self.job.id,
            task_id=self.row.task_id,
            demonstrator_id=self.demonstrator.id,
        )


def add_reward(
    session: Session,
    job: Job,
    *,
    ordinal: int,
    n_actions: int,
    reward: np.ndarray,
    value: np.ndarray | None = None,
    policy: np.ndarray | None = None,
    uncertainty: np.ndarray | None = None,
    evidence: np.ndarray | None = None,
) -> Reward:
    """Add one result row of `job` (ordinal 0: the baseline; i + 1: task i) with its arrays and summary:
    ``uncertainty`` the reward's spread across the ensemble's members, ``evidence`` the demonstrations'.

    The summary is computed here, once, so listing a job's rewards never loads their arrays.
    """
    task_id = job.task_ids[ordinal - 1] if ordinal else None
    lab_id = job.lab_id
    row = Reward(
        id=new_id("rwd"),
        lab_id=lab_id,
        job_id=job.id,
        ordinal=ordinal,
        kind="task" if task_id else "baseline",
        task_id=task_id,
        n_states=int(reward.shape[0]),
        n_actions=n_actions,
        reward_blob_id=put_array(session, reward, lab_id=lab_id),
        value_blob_id=None if value is None else put_array(session, value, lab_id=lab_id),
        policy_blob_id=None if policy is None else put_array(session, policy, lab_id=lab_id),
        uncertainty_blob_id=None if uncertainty is None else put_array(session, uncertainty, lab_id=lab_id),
        evidence_blob_id=None if evidence is None else put_array(session, evidence, lab_id=lab_id),
        summary=exports.summary(reward),
    )
    session.add(row)
    return row


def reward_context(session: Session, reward_id: str, *, lab_id: str) -> RewardContext:
    """The lab's reward `reward_id` with its job, task, demonstrator and MDP; 404 for another lab's."""
    return context(session, get_owned(session, Reward, reward_id, lab_id=lab_id, what="reward"))


def job_rewards(session: Session, job: Job, *, exclude_top_truth: bool) -> JobRewards:
    """The baseline and every task reward with summary, truth scores (against the current true reward), links."""
    refs = []
    for row in job_reward_rows(session, job):
        ctx = context(session, row)
        truth = load_true_reward(session, row.task_id) if row.task_id else None
        values = None if truth is None else get_array(session, row.reward_blob_id)
        refs.append(
            RewardRef(
                reward_id=row.id,
                kind="task" if ctx.task else "baseline",
                task_id=row.task_id,
                task_name=ctx.task.name if ctx.task else None,
                n_states=row.n_states,
                n_actions=row.n_actions,
                summary=RewardSummary.model_validate(row.summary),
                truth_pearson=None if values is None or truth is None else metrics().pearson(values, truth),
                truth_pearson_excluding_top=(
                    pearson_below_top(values, truth) if exclude_top_truth and values is not None else None
                ),
                links=reward_links(
                    row.id,
                    drawable=ctx.layout is not None,
                    task=ctx.task is not None,
                    stored=tuple(
                        q
                        for q, blob in (
                            ("uncertainty", row.uncertainty_blob_id),
                            ("evidence", row.evidence_blob_id),
                        )
                        if blob is not None
                    ),
                ),
                note=None if ctx.task else baseline_note(job, ctx.layout),
            )
        )
    return JobRewards(job_id=job.id, demonstrator_id=job.demonstrator_id, baseline=refs[0], tasks=refs[1:])


MEAN_OF_TASKS = (
    'No baseline reward was learned (sharing "none", or the maxent method): this is the mean of the task '
    "rewards, a summary of them rather than an estimate of the demonstrator's inherent reward."
)


def baseline_note(job: Job, layout: Layout | None) -> str | None:
    """What a reader of this job's baseline must know: that it is no estimate (the networks without sharing,
    maxent; ``shared_maxent`` always learns one), or its caveat on a velocity grid (out-and-back movements do
    not identify all of it; docs/motion.md)."""
    method = job.config.get("method", "meta_irl")
    if method == "maxent" or (method == "meta_irl" and job.config.get("sharing") == "none"):
        return MEAN_OF_TASKS
    if layout is not None and layout.channels == 8:
        return BASELINE_CAVEAT
    return None


def require_succeeded(job: Job) -> None:
    """409 unless the job has succeeded (only then does it have rewards)."""
    if job.status != JobStatus.SUCCEEDED:
        raise Conflict(f"Job {job.id} is {job.status}; rewards exist once it has succeeded.")


def context(session: Session, row: Reward) -> RewardContext:
    """Load what names and draws `row`; the baseline is drawn on the MDP of the job's first task."""
    job = session.get_one(Job, row.job_id)
    task = session.get_one(Task, row.task_id) if row.task_id else None
    mdp_id = (task or session.get_one(Task, job.task_ids[0])).mdp_id
    return RewardContext(
        row=row,
        job=job,
        task=task,
        demonstrator=session.get_one(Demonstrator, job.demonstrator_id),
        mdp=session.get_one(Mdp, mdp_id),
    )


def job_reward_rows(session: Session, job: Job) -> list[Reward]:
    """The job's reward rows, baseline first then tasks in the job's order."""
    return list(
        session.execute(select(Reward).where(Reward.job_id == job.id).order_by(Reward.ordinal)).scalars()
    )


def blob_id_of(row: Reward, quantity: Quantity) -> str:
    """The blob holding `quantity` of `row`; 409 where the row has none (`not_stored`)."""
    blob_id = {
        "reward": row.reward_blob_id,
        "value": row.value_blob_id,
        "policy": row.policy_blob_id,
        "uncertainty": row.uncertainty_blob_id,
        "evidence": row.evidence_blob_id,
    }[quantity]
    if blob_id is None:
        raise not_stored(quantity, row.id)
    return blob_id


def not_stored(quantity: Quantity, reward_id: str) -> Conflict:
    """The 409 for a quantity a reward row lacks: a baseline's value function or policy, the spread of a fit
    with one ensemble member, or what rows stored before it was kept lack."""
    if quantity == "uncertainty":
        return Conflict(
            f"Reward {reward_id} has no uncertainty: its fit ran a single ensemble member (a tabular method, "
            "among them the shared solver that config tabular_choice picks for an MDP without features (or whose "
            "features only say where a state is) where it "
            "predicts held-out demonstrations better; config ensemble 1; or a large fit's automatic choice), so "
            "there is no spread across members, or it was stored before the spread was kept. "
            "?quantity=evidence says where the demonstrations give evidence. For a spread, rerun the job with "
            "config ensemble ≥ 2 (and tabular_choice false to keep the networks)."
        )
    if quantity == "evidence":
        return Conflict(f"Reward {reward_id} was stored before evidence was kept; rerun the job to get it.")
    return Conflict(
        f"Reward {reward_id} is the baseline, which has no {quantity}; ask a task's reward for its value or policy."
    )


def pearson_below_top(values: np.ndarray, truth: np.ndarray | None) -> float | None:
    """Pearson r on the states whose true reward is below its maximum; None without truth or two such states."""
    if truth is None:
        return None
    below = truth < truth.max()
    return metrics().pearson(values, truth, mask=below) if below.sum() >= 2 else None
