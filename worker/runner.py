"""Run one claimed attempt of a job: load its inputs, fit with the engine, store the results — fenced by attempt.

The fit runs in the calling (pool) thread while the attempt's `Monitor` thread keeps its heartbeat,
progress and cancel flag. Results (rewards and every step's losses) and the status change to succeeded
are one transaction, applied only if this attempt still owns the row.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path

import torch
from billiard.exceptions import SoftTimeLimitExceeded
from sqlalchemy.orm import Session, sessionmaker

from metairl_engine.config import FitConfig
from metairl_engine.errors import Cancelled, Diverged, InvalidInput
from metairl_engine.evidence import tasks_evidence
from metairl_engine.fit import FitResult, TaskData, fit
from service.jobs.transitions import owned_by, transition
from service.results.rewards import add_reward
from service.settings import Settings, WorkerDevice, get_settings
from service.store.histories import add_step_history
from service.store.loaders import load_mdp, load_trajectories
from service.store.models.demonstrators import Task
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job
from worker.context import sessions
from worker.memory import OverBudget, check_memory
from worker.monitor import Monitor, progress_values

log = logging.getLogger(__name__)


def run_attempt(job_id: str, attempt: int, monitor: Monitor) -> None:
    """Run attempt ``attempt`` of job ``job_id`` (claimed, its `monitor` beating) to a final status.

    Nothing is written once the attempt has lost the job (the monitor found another attempt owns it).
    """
    settings = get_settings()
    make_session = sessions()
    task_ids: list[str] = []
    try:
        try:
            device = fit_device(settings.worker_device)
            with make_session() as session:
                job = session.get_one(Job, job_id)
                task_ids = list(job.task_ids)
                config = FitConfig.from_dict(job.config)
                check_memory(session, job_id, task_ids, config, settings)
                tasks = load_tasks(session, task_ids)
            torch.set_num_threads(
                torch_threads(
                    settings.worker_concurrency,
                    size=tasks[0].mdp.n_states * len(tasks),
                    threads=settings.worker_threads,
                )
            )
            result = fit(
                tasks, config, progress=monitor.report, should_stop=monitor.should_stop, device=device
            )
        finally:
            monitor.close()  # the last progress sample is written before the final status
    except Cancelled:
        if monitor.lost:
            log.warning("job %s: attempt %d lost the job to another attempt; stopped", job_id, attempt)
            return
        finish(make_session, job_id, attempt, JobStatus.CANCELLED, message="cancelled on request")
    except Exception as exc:
        log.exception("job %s: attempt %d failed", job_id, attempt)
        reason = explain_failure(exc, task_ids=task_ids, settings=settings)
        finish(make_session, job_id, attempt, JobStatus.FAILED, values={"error": reason}, message=reason)
    else:
        store_results(make_session, job_id, attempt, result=result, tasks=tasks)


SMALL_PROBLEM = 20_000
"""Below this many (task, state) rows a fit gets one torch thread: a second one gains nothing there, and
when the cores are shared, threads spinning on tiny ops made fits 5-10x slower (measured: 1.3 s vs 9.6 s
for a 4-task, 100-state fit beside one busy process)."""


def torch_threads(concurrency: int, *, size: int, threads: int = 0) -> int:
    """Threads per job: ``threads`` (``METAIRL_WORKER_THREADS``) or, with 0, the cores this process may use
    shared by the jobs it runs at once; one for small fits either way."""
    if size < SMALL_PROBLEM:
        return 1
    return threads or max(1, usable_cores() // max(1, concurrency))


CPU_MAX = Path("/sys/fs/cgroup/cpu.max")
"""cgroup v2's CPU quota of this process's group: "<quota> <period>" in µs, or "max <period>" (no quota)."""


def usable_cores(cpu_max: Path = CPU_MAX) -> int:
    """The cores this process may use: its CPU affinity, capped by its cgroup's CPU quota (what a container's
    ``cpus:`` sets; it limits CPU time, not affinity, so threads counted from the affinity alone would
    oversubscribe the quota)."""
    cores = len(os.sched_getaffinity(0))
    try:
        quota, period = cpu_max.read_text().split()[:2]
        return max(1, min(cores, int(quota) // int(period)))
    except (OSError, ValueError):  # no cgroup v2 file, or "max": no quota
        return cores


class NoCuda(Exception):
    """``METAIRL_WORKER_DEVICE=cuda`` on a worker where torch sees no CUDA GPU; the message says what to do."""


def fit_device(setting: WorkerDevice) -> str:
    """The torch device for a fit from ``METAIRL_WORKER_DEVICE``: ``auto`` is "cuda" when torch sees a CUDA
    GPU, else "cpu"; ``cuda`` without one raises `NoCuda`, so the job fails saying why instead of running slowly."""
    if setting == "cpu":
        return "cpu"
    if torch.cuda.is_available():
        return "cuda"
    if setting == "cuda":
        raise NoCuda(
            "This worker is set to fit on a GPU (METAIRL_WORKER_DEVICE=cuda) but torch sees no CUDA GPU "
            f"(torch {torch.__version__}, CUDA build: {torch.version.cuda or 'none'}). The operator should give "
            "the worker a GPU and a CUDA build of torch, or set METAIRL_WORKER_DEVICE=auto or cpu; "
            "submit the job again once that is done."
        )
    return "cpu"


def load_tasks(session: Session, task_ids: Sequence[str]) -> list[TaskData]:
    """The engine's view of each task: its MDP and trajectories (MDPs shared by tasks are loaded once)."""
    mdps = {}
    out = []
    for task_id in task_ids:
        task = session.get_one(Task, task_id)
        if task.mdp_id not in mdps:
            mdps[task.mdp_id] = load_mdp(session, task.mdp_id)
        out.append(
            TaskData(mdp=mdps[task.mdp_id], trajectories=load_trajectories(session, task_id), name=task_id)
        )
    return out


def explain_failure(exc: BaseException, *, task_ids: Sequence[str], settings: Settings) -> str:
    """A sentence a person can act on: which input or limit, and what to change."""
    if isinstance(exc, InvalidInput):
        issues = "; ".join(f"{name_pointer(i.pointer, task_ids)}: {i.message}" for i in exc.issues[:5])
        return f"The engine rejected the job's inputs — {issues}. Fix or remove the named task and submit a new job."
    if isinstance(exc, SoftTimeLimitExceeded):
        return (
            f"The job ran longer than the limit of {settings.job_time_limit_s} s; lower config.max_steps, "
            "fit fewer or smaller tasks, or ask the operator to raise METAIRL_JOB_TIME_LIMIT_S."
        )
    if isinstance(exc, OverBudget | NoCuda | Diverged):
        return str(exc)
    if isinstance(exc, MemoryError):
        return (
            "The worker ran out of memory; use smaller config.hidden layers or fewer states, "
            "or run the job on a worker with more memory."
        )
    return (
        f"The job failed unexpectedly ({type(exc).__name__}: {exc}). This is a bug in metairl: "
        "please report it with the job id; resubmitting with a different config.seed may avoid it."
    )


def name_pointer(pointer: str, task_ids: Sequence[str]) -> str:
    """Replace the engine's ``/tasks/<i>`` pointer prefix by the task's id (``task task_…/…``)."""
    parts = pointer.split("/")
    if len(parts) > 2 and parts[1] == "tasks" and parts[2].isdigit() and int(parts[2]) < len(task_ids):
        rest = "/".join(parts[3:])
        return f"task {task_ids[int(parts[2])]}" + (f" /{rest}" if rest else "")
    return pointer or "/"


def finish(
    make_session: sessionmaker[Session],
    job_id: str,
    attempt: int,
    status: JobStatus,
    *,
    values: dict[str, object] | None = None,
    message: str,
) -> None:
    """End this attempt's job as ``status`` (cancelled or failed) if the attempt still owns it."""
    with make_session() as session:
        changed = transition(
            session,
            job_id,
            JobStatus.RUNNING,
            status,
            where=owned_by(attempt),
            values=values,
            message=message,
        )
        if changed is not None:
            session.commit()
            log.info("job %s: %s", job_id, status.value)


def store_results(
    make_session: sessionmaker[Session],
    job_id: str,
    attempt: int,
    *,
    result: FitResult,
    tasks: Sequence[TaskData] = (),
) -> None:
    """Write every reward, value and policy, with each reward's spread across the ensemble's members and
    the evidence the demonstrations of ``tasks`` give per state (none without tasks), the fit's per-step
    history and its shrinkage λ and sparsity q (none with the tabular methods, which shrink nothing), and mark the
    job succeeded with the config as fitted (`FitConfig.task_features` ``auto`` replaced by its choice), in one
    transaction, if still owned."""
    n_actions = result.policies.shape[2]
    base_evidence, task_evidence = tasks_evidence(tasks) if tasks else (None, [None] * len(result.rewards))
    with make_session() as session:
        last = result.history[-1] if result.history else None
        done = transition(
            session,
            job_id,
            JobStatus.RUNNING,
            JobStatus.SUCCEEDED,
            where=owned_by(attempt),
            values={
                "best_step": result.best_step,
                "config": result.config.to_dict(),  # as fitted: a choice `auto` left to the fit, made
                "shrinkage": None if result.config.method != "meta_irl" else result.shrinkage,
                "sparsity": None if result.config.method != "meta_irl" else result.sparsity,
                **progress_values(last),
            },
            message=f"finished after {len(result.history)} steps (kept step {result.best_step})",
        )
        if done is None:
            log.warning("job %s: attempt %d no longer owns the job; results discarded", job_id, attempt)
            return
        job = session.get_one(Job, job_id)
        add_reward(
            session,
            job,
            ordinal=0,
            n_actions=n_actions,
            reward=result.baseline,
            uncertainty=result.baseline_spread,
            evidence=base_evidence,
        )
        for i in range(len(result.rewards)):
            add_reward(
                session,
                job,
                ordinal=i + 1,
                n_actions=n_actions,
                reward=result.rewards[i],
                value=result.values[i],
                policy=result.policies[i],
                uncertainty=None if result.reward_spread is None else result.reward_spread[i],
                evidence=task_evidence[i],
            )
        add_step_history(session, job_id, attempt, result.history)
        session.commit()
    log.info("job %s: succeeded", job_id)
