"""`metairl demo`: the paper's terrain experiment (§IV-A, Fig. 2) end to end over the HTTP API.

Generates seeded hilly worlds with goal tasks and Boltzmann-rational demonstrations, uploads them (one
MDP and one demonstrator per world, one task per goal with its demonstrations and true reward), submits a
job per (world, task count, sharing loss), follows them with progress bars, downloads the learned rewards,
scores them client-side and writes the figure, heatmaps and tables (see `metairl_cli.demo_report`).
Never imports torch: the client side is numpy, httpx and matplotlib.
"""

from __future__ import annotations

import os
import sys
import time
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy.orm import Session
from tqdm import tqdm

from metairl_cli.demo_experiment import (
    FULL,
    QUICK,
    DemoSettings,
    JobOutcome,
    JobPlan,
    SimWorld,
    make_experiment,
    plan_jobs,
)
from metairl_cli.demo_report import write_report
from metairl_cli.serve import local_key
from metairl_client import APIConnectionError, Client, JobState, MetairlError
from metairl_engine.sim.terrain import World
from service.settings import Settings, get_settings
from service.store.db import make_engine, migrate, missing_sqlite_file

API_KEY_ENV = "METAIRL_API_KEY"
POLL_S = 0.5
"""Seconds between two polls of the jobs in flight."""
IN_FLIGHT = 4
"""Jobs submitted ahead of the worker; more would only make each poll longer."""


def run_demo(*, url: str, api_key: str | None, out: str, quick: bool) -> int:
    """Run the experiment against the service at ``url`` and write results into ``out``; exit code.

    0 when every job succeeded, 1 when the service answered an error (printed with its fields), could not
    be reached, or some job failed (the results of the others are still written), 2 without a key to use,
    130 on Ctrl-C.
    """
    settings = QUICK if quick else FULL
    try:
        key = resolve_api_key(api_key, settings=get_settings())
        with Client.connect(url=url, api_key=key) as api:
            return run_experiment(api, settings, out=Path(out))
    except NoLocalKey as exc:
        print(f"metairl demo: {exc}", file=sys.stderr)
        return 2
    except APIConnectionError as exc:
        print(
            f"metairl demo: cannot reach the service at {url} ({exc.detail}); start it with `bash scripts/serve.sh`.",
            file=sys.stderr,
        )
    except MetairlError as exc:
        print(f"metairl demo: the service refused a request:\n{exc}", file=sys.stderr)
    except KeyboardInterrupt:
        print("metairl demo: interrupted; jobs in flight were cancelled.", file=sys.stderr)
        return 130
    return 1


class NoLocalKey(Exception):
    """No key was given and there is no local database to take the ``local`` lab's key from."""


def resolve_api_key(api_key: str | None, *, settings: Settings) -> str:
    """The key to use: the one given, else ``$METAIRL_API_KEY``, else the ``local`` lab's key that `metairl serve`
    keeps in the data folder (minted and kept there only if missing or revoked, as `serve` does).

    Never creates a database: `NoLocalKey` when the settings name a SQLite file that does not exist (the demo was
    started away from the service's data folder), which would otherwise mint a key the service never sees."""
    if api_key:
        return api_key
    if os.environ.get(API_KEY_ENV):
        return os.environ[API_KEY_ENV]
    missing = missing_sqlite_file(settings)
    if missing is not None:
        raise NoLocalKey(
            f"no API key given, and no metairl database at {missing}. Run the demo with the METAIRL_DATA_DIR of "
            f"the running service (now {settings.data_dir.resolve()}), where `metairl serve` keeps the local key, "
            f"or pass --api-key (or set {API_KEY_ENV})."
        )
    engine = make_engine(settings)
    try:
        migrate(engine)
        with Session(engine) as session:
            return local_key(session, settings.data_dir)
    finally:
        engine.dispose()


def run_experiment(api: Client, settings: DemoSettings, *, out: Path) -> int:
    """Generate, upload, fit and report; prints the accuracy table; 0 if every job succeeded, else 1."""
    api.check_health()
    started = time.monotonic()
    worlds = make_experiment(settings)
    uploaded = [
        upload_world(api, sim)
        for sim in tqdm(worlds, desc="uploading worlds", unit="world", disable=None, file=sys.stderr)
    ]
    outcomes = run_jobs(api, uploaded, settings)
    table = write_report(out, settings, worlds, outcomes)
    print(f"\nPearson r of learned task rewards with the truth (goal excluded), mean ± sd:\n\n{table}\n")
    failed = [o for o in outcomes if not o.succeeded]
    print(
        f"{len(outcomes) - len(failed)}/{len(outcomes)} jobs succeeded in {time.monotonic() - started:.0f} s; results in {out}/"
    )
    for o in failed:
        print(
            f"  job {o.job_id} ({o.plan.describe()}) {o.status}: {o.error}",
            file=sys.stderr,
        )
    return 1 if failed else 0


@dataclass(frozen=True)
class UploadedWorld:
    """A world as stored by the service: its MDP, its demonstrator and one task id per goal task."""

    sim: SimWorld
    mdp_id: str
    demonstrator_id: str
    task_ids: tuple[str, ...]


def mdp_body(world: World, *, name: str) -> dict[str, Any]:
    """The explicit deterministic `POST /v1/mdps` body of a terrain: next states, coordinate features, layout."""
    mdp = world.mdp
    assert mdp.next_state is not None and mdp.features is not None and mdp.layout is not None
    return {
        "kind": "explicit",
        "name": name,
        "n_states": mdp.n_states,
        "n_actions": mdp.n_actions,
        "gamma": mdp.gamma,
        "features": mdp.features.tolist(),
        "transitions": {"kind": "deterministic", "next_state": mdp.next_state.tolist()},
        "layout": {"width": mdp.layout.width, "height": mdp.layout.height, "channels": mdp.layout.channels},
    }


def upload_world(api: Client, sim: SimWorld) -> UploadedWorld:
    """Create the world's MDP and demonstrator, then per goal a task with its demonstrations and true reward."""
    label = f"terrain world {sim.index}"
    mdp_id = api.create_mdp(mdp_body(sim.world, name=label))
    demonstrator_id = api.create_demonstrator(
        name=f"{label} demonstrator", metadata={"experiment": "metairl demo", "world": sim.index}
    )
    task_ids = []
    for task in sim.tasks:
        task_id = api.create_task(
            demonstrator_id, name=task.name, mdp_id=mdp_id, metadata={"goal": task.goal}
        )
        api.add_demonstrations(task_id, task.trajectories)
        api.put_true_reward(task_id, task.true_reward)
        task_ids.append(task_id)
    return UploadedWorld(sim=sim, mdp_id=mdp_id, demonstrator_id=demonstrator_id, task_ids=tuple(task_ids))


def run_jobs(api: Client, worlds: Sequence[UploadedWorld], settings: DemoSettings) -> list[JobOutcome]:
    """Submit every planned job (at most `IN_FLIGHT` ahead), follow them with progress bars, collect outcomes.

    On Ctrl-C the jobs in flight are cancelled before the interrupt propagates.
    """
    pending = deque(plan_jobs(settings))
    total = len(pending)
    in_flight: dict[str, JobPlan] = {}
    outcomes: dict[JobPlan, JobOutcome] = {}
    step_bar = StepBar(total=settings.max_steps)
    try:
        with tqdm(
            total=total, desc="jobs", unit="job", position=0, disable=None, file=sys.stderr
        ) as jobs_bar:
            while pending or in_flight:
                while pending and len(in_flight) < IN_FLIGHT:
                    plan = pending.popleft()
                    world = worlds[plan.world]
                    job = api.submit_job(
                        world.demonstrator_id,
                        task_ids=world.task_ids[: plan.n_tasks],
                        config=settings.job_config(plan.loss),
                    )
                    in_flight[job.id] = plan
                for job_id, plan in list(in_flight.items()):
                    state = api.get_job(job_id)
                    if state.finished:
                        outcomes[plan] = collect(api, worlds[plan.world], plan, state)
                        del in_flight[job_id]
                        jobs_bar.update()
                    elif state.status == "running":
                        step_bar.show(plan, state)
                if in_flight:
                    time.sleep(POLL_S)
    except KeyboardInterrupt:
        cancel_all(api, in_flight)
        raise
    finally:
        step_bar.close()
    return [outcomes[plan] for plan in plan_jobs(settings)]


class StepBar:
    """A progress bar of the running job's optimisation steps, reset whenever another job starts running."""

    def __init__(self, *, total: int):
        self.bar = tqdm(
            total=total,
            desc="waiting for the worker",
            unit="step",
            position=1,
            leave=False,
            disable=None,
            file=sys.stderr,
        )
        self.job_id: str | None = None

    def show(self, plan: JobPlan, state: JobState) -> None:
        """Move the bar to the job's latest reported step (a new job restarts it at 0)."""
        if state.id != self.job_id:
            self.job_id = state.id
            self.bar.reset(total=state.max_steps or self.bar.total)
            self.bar.set_description(plan.describe())
        self.bar.update((state.step or 0) - self.bar.n)

    def close(self) -> None:
        """Remove the bar from the terminal."""
        self.bar.close()


def collect(api: Client, world: UploadedWorld, plan: JobPlan, state: JobState) -> JobOutcome:
    """A finished job's outcome: for a success, its downloaded rewards scored against the true ones."""
    if state.status != "succeeded":
        tqdm.write(f"job {state.id} {state.status}: {state.error}", file=sys.stderr)
        return JobOutcome(plan=plan, job_id=state.id, status=state.status, error=state.error)
    ids = api.job_rewards(state.id)
    task_ids = world.task_ids[: plan.n_tasks]
    reward_ids = tuple(ids.tasks[t] for t in task_ids)
    return JobOutcome.scored(
        world.sim,
        plan,
        job_id=state.id,
        task_ids=task_ids,
        reward_ids=reward_ids,
        baseline_reward_id=ids.baseline,
        rewards=np.stack([api.reward_values(r) for r in reward_ids]),
        baseline=api.reward_values(ids.baseline),
    )


def cancel_all(api: Client, job_ids: Iterable[str]) -> None:
    """Ask the service to cancel each job (one that already finished answers 409, which is fine)."""
    for job_id in job_ids:
        try:
            api.cancel_job(job_id)
        except MetairlError as exc:
            if exc.status != 409:
                tqdm.write(f"could not cancel job {job_id}:\n{exc}", file=sys.stderr)
