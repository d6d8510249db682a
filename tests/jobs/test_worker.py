"""Jobs run by real worker processes, on the embedded backend (SQLite + filesystem broker) and on
PostgreSQL + Redis or RabbitMQ: results and downloads, progress, cancel, engine failures, lost and
duplicate messages, and a killed worker."""

from __future__ import annotations

import io
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
import torch
from sqlalchemy import func, select

from metairl_engine.config import MAX_AUTO_MEMBERS, FitConfig
from metairl_engine.fit import fit
from metairl_engine.shrinkage import SHRINKAGE
from metairl_engine.sim.benchmark import goal_tasks
from metairl_engine.sim.objectworld import make_objectworld
from service.jobs.queue import CeleryJobQueue
from service.store.ids import new_id
from service.store.models.base import utcnow
from service.store.models.demonstrators import Task
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, Reward, StepHistory
from tests.jobs.conftest import REPO, Stack, settings_environment
from tests.jobs.helpers import (
    ENDLESS,
    LONG,
    QUICK,
    all_events,
    demonstrated_tasks,
    ring_tasks,
    submit,
    unsent_job,
    wait_for,
)
from tests.service.helpers import add_demonstrations, make_demonstrator, make_mdp, make_task
from worker.reaper import RESENT
from worker.runner import load_tasks

pytestmark = [pytest.mark.worker, pytest.mark.slow]


def reward_rows(stack: Stack, job_id: str) -> int:
    """How many reward rows the job has in the database."""
    with stack.client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
        return session.execute(
            select(func.count()).select_from(Reward).where(Reward.job_id == job_id)
        ).scalar_one()


def test_job_succeeds_and_its_rewards_download_as_json_and_npy(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, task_ids = demonstrated_tasks(client, auth)
    job = wait_for(client, auth, submit(client, auth, demonstrator_id, QUICK)["id"])
    assert job["status"] == "succeeded", job
    assert (job["attempts"], job["progress"]["step"], job["error"]) == (1, QUICK["max_steps"], None)
    assert job["started_at"] <= job["finished_at"]

    rewards = client.get(f"/v1/jobs/{job['id']}/rewards", headers=auth).json()
    assert [t["task_id"] for t in rewards["tasks"]] == task_ids
    assert reward_rows(stack, job["id"]) == 1 + len(task_ids)
    for ref in [rewards["baseline"], *rewards["tasks"]]:
        as_json = client.get(f"/v1/rewards/{ref['reward_id']}", headers=auth).json()
        assert (as_json["reward_id"], as_json["n_states"], len(as_json["values"])) == (ref["reward_id"], 3, 3)
        npy = client.get(f"/v1/rewards/{ref['reward_id']}", params={"format": "npy"}, headers=auth)
        array = np.load(io.BytesIO(npy.content))
        assert array.dtype == np.float32 and array.shape == (3,)
        np.testing.assert_array_equal(array, np.asarray(as_json["values"], dtype=np.float32))
    task_reward = rewards["tasks"][0]["reward_id"]
    policy = client.get(
        f"/v1/rewards/{task_reward}", params={"quantity": "policy", "format": "npy"}, headers=auth
    )
    policy_array = np.load(io.BytesIO(policy.content))
    assert policy_array.shape == (3, 2)
    np.testing.assert_allclose(policy_array.sum(axis=1), 1.0, rtol=1e-5)
    value = client.get(f"/v1/rewards/{task_reward}", params={"quantity": "value"}, headers=auth).json()
    assert len(value["values"]) == 3 and value["quantity"] == "value"
    baseline_value = client.get(
        f"/v1/rewards/{rewards['baseline']['reward_id']}", params={"quantity": "value"}, headers=auth
    )
    assert baseline_value.status_code == 409


def test_a_succeeded_job_states_the_ensemble_members_its_automatic_ensemble_fitted(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, _ = demonstrated_tasks(client, auth)
    queued = submit(client, auth, demonstrator_id, QUICK | {"tabular_choice": False})  # the networks, surely
    assert queued["config"]["ensemble"] == 0  # automatic: the fit picks K
    job = wait_for(client, auth, queued["id"])
    assert job["status"] == "succeeded", job
    # 2 tasks of 3 states are far within the budget: the most members the automatic ensemble uses.
    assert job["config"] == queued["config"] | {"ensemble": MAX_AUTO_MEMBERS}
    assert job["ignored_settings"] == []


def test_a_succeeded_job_keeps_every_step_and_the_shrinkage_and_sparsity_the_engine_computed(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, task_ids = demonstrated_tasks(client, auth)
    config = QUICK | {"holdout_fraction": 0.5}  # a held-out NLL at every step
    queued = submit(client, auth, demonstrator_id, config)
    assert queued["shrinkage"] is None and queued["sparsity"] is None
    job = wait_for(client, auth, queued["id"])
    assert job["status"] == "succeeded", job
    history = client.get(f"/v1/jobs/{job['id']}/history", headers=auth).json()
    assert (history["source"], history["attempt"], history["best_step"]) == ("steps", 1, job["best_step"])
    points = history["points"]
    assert [p["step"] for p in points] == list(range(1, job["progress"]["step"] + 1))  # one per step
    assert points[-1] == {k: v for k, v in job["progress"].items() if k != "max_steps"}

    # The same fit again, here: the stored steps are the engine's history, loss for loss.
    torch.set_num_threads(1)  # as the worker fits a problem this small
    with stack.client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
        tasks = load_tasks(session, task_ids)
    again = fit(tasks, FitConfig.from_dict(job["config"]))
    assert job["shrinkage"] in SHRINKAGE and job["shrinkage"] == again.shrinkage
    assert job["sparsity"] == again.sparsity
    assert len(again.history) == len(points)
    for point, step in zip(points, again.history, strict=True):
        assert point["heldout_nll"] is not None
        assert (
            point["step"],
            point["loss"],
            point["irl_loss"],
            point["sharing_loss"],
            point["heldout_nll"],
        ) == (
            step.step,
            step.loss,
            step.irl_loss,
            step.sharing_loss,
            step.heldout_nll,
        )
    with stack.client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
        stored = session.get_one(StepHistory, job["id"])
        assert (stored.n_steps, len(stored.data)) == (len(points), 48 * len(points))


def test_an_objectworld_sent_over_http_is_fitted_with_the_default_config_as_a_notebook_fits_it(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    """A published benchmark world — wind (sparse stochastic moves), distance features of up to several cells
    — with goal tasks, uploaded as a lab would and fitted with no config: the served rewards are the engine's."""
    client, auth = stack.client, stack.auth
    world = make_objectworld(seed=3, size=6)[0]
    mdp = world.mdp
    assert mdp.sparse is not None and mdp.features is not None and float(mdp.features.max()) > 1
    body = {
        "name": "objectworld",
        "n_states": mdp.n_states,
        "n_actions": mdp.n_actions,
        "gamma": mdp.gamma,
        "features": mdp.features.tolist(),
        "transitions": {
            "kind": "sparse",
            **{k: getattr(mdp.sparse, k).tolist() for k in ("s", "a", "next", "p")},
        },
        "layout": {"width": 6, "height": 6},
    }
    mdp_id = make_mdp(client, auth, **body)["id"]
    demonstrator_id = make_demonstrator(client, auth, name="objectworld demonstrator")["id"]
    task_ids = []
    for sim in goal_tasks(world, n_tasks=2, n_demos=3, seed=0, goal_bonus=10.0):
        task_id = make_task(client, auth, demonstrator_id=demonstrator_id, mdp_id=mdp_id)["id"]
        paths = [{"states": t.states.tolist(), "actions": t.actions.tolist()} for t in sim.trajectories]
        add_demonstrations(client, auth, task_id, paths)
        task_ids.append(task_id)

    job = wait_for(client, auth, submit(client, auth, demonstrator_id, {})["id"], timeout=180)
    assert job["status"] == "succeeded", job
    served = client.get(f"/v1/jobs/{job['id']}/rewards", headers=auth).json()["tasks"]
    torch.set_num_threads(1)  # as the worker fits a problem this small
    with stack.client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
        again = fit(load_tasks(session, task_ids), FitConfig())
    for i, ref in enumerate(served):
        npy = client.get(f"/v1/rewards/{ref['reward_id']}", params={"format": "npy"}, headers=auth)
        np.testing.assert_array_equal(np.load(io.BytesIO(npy.content)), again.rewards[i])


def test_running_job_reports_progress_and_cancels_within_seconds(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, _ = ring_tasks(client, auth)
    running = submit(client, auth, demonstrator_id, ENDLESS)["id"]
    first = wait_for(client, auth, running, lambda j: (j["progress"] or {}).get("step", 0) >= 1)
    waiting = submit(client, auth, demonstrator_id, QUICK)["id"]  # the only worker slot is taken
    later = wait_for(
        client, auth, running, lambda j: j["progress"]["step"] > first["progress"]["step"], timeout=10
    )
    assert later["status"] == "running" and later["progress"]["elapsed_s"] > first["progress"]["elapsed_s"]

    queued_cancel = client.post(f"/v1/jobs/{waiting}/cancel", headers=auth).json()
    assert queued_cancel["status"] == "cancelled"

    asked = time.monotonic()
    assert client.post(f"/v1/jobs/{running}/cancel", headers=auth).json()["cancel_requested"] is True
    ended = wait_for(client, auth, running, timeout=10)
    assert ended["status"] == "cancelled" and time.monotonic() - asked < 5
    assert client.post(f"/v1/jobs/{running}/cancel", headers=auth).status_code == 409

    events = all_events(client, auth, running)
    steps = [e["step"] for e in events if e["kind"] == "progress"]
    assert len(steps) >= 2 and steps == sorted(set(steps))
    assert [e["status"] for e in events if e["kind"] == "status"] == ["queued", "running", "cancelled"]
    history = client.get(f"/v1/jobs/{running}/history", headers=auth).json()
    assert history["source"] == "samples" and [p["step"] for p in history["points"]] == steps

    time.sleep(1.5)  # the worker now reaches the cancelled job's message and must skip it
    skipped = client.get(f"/v1/jobs/{waiting}", headers=auth).json()
    assert (skipped["status"], skipped["attempts"]) == ("cancelled", 0)


def test_engine_failure_fails_the_job_with_a_sentence_naming_the_task(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    """Inputs the API would refuse, written to the database directly: the engine's own check must catch them."""
    client, auth = stack.client, stack.auth
    demonstrator_id, [task_id] = demonstrated_tasks(client, auth, 1)
    three_actions = make_mdp(
        client,
        auth,
        n_actions=3,
        transitions={"kind": "deterministic", "next_state": [[0, 1, 0], [0, 2, 1], [1, 2, 2]]},
    )
    odd_task = make_task(client, auth, demonstrator_id=demonstrator_id, mdp_id=three_actions["id"])["id"]
    add_demonstrations(client, auth, odd_task)
    with client.app.state.sessionmaker() as session:  # type: ignore[attr-defined]
        job = Job(
            id=new_id("job"),
            lab_id=session.get_one(Task, task_id).lab_id,
            demonstrator_id=demonstrator_id,
            task_ids=[task_id, odd_task],
            config=dict(QUICK),
            status=JobStatus.QUEUED.value,
            cancel_requested=False,
            attempts=0,
            max_attempts=1,
            updated_at=utcnow(),
        )
        session.add(job)
        session.commit()
    CeleryJobQueue(stack.settings).enqueue(job.id)
    failed = wait_for(client, auth, job.id)
    assert failed["status"] == "failed"
    assert failed["error"].startswith("The engine rejected the job's inputs")
    assert f"task {odd_task}" in failed["error"] and "3 actions" in failed["error"]
    assert reward_rows(stack, job.id) == 0


def status_events(stack: Stack, job_id: str) -> list[tuple[str, int]]:
    """(status, attempt) of each status event of the job, in order."""
    events = all_events(stack.client, stack.auth, job_id)
    return [(e["status"], e["attempt"]) for e in events if e["kind"] == "status"]


def failure_on_a_worker_with(stack: Stack, worker: subprocess.Popen[bytes], **settings: object) -> str:
    """Run a quick job on a worker started with these settings instead of ``worker``; the job must fail on its
    first attempt, without retries, progress or rewards: returns its error."""
    client, auth = stack.client, stack.auth
    demonstrator_id, _ = demonstrated_tasks(client, auth)
    stack.workers.kill(worker)
    other = stack.workers.start(**settings)
    try:
        job_id = submit(client, auth, demonstrator_id, QUICK)["id"]
        failed = wait_for(client, auth, job_id)
    finally:
        stack.workers.kill(other)  # the next test's worker has the stack's settings again
    assert (failed["status"], failed["attempts"], failed["progress"]) == ("failed", 1, None), failed
    assert status_events(stack, job_id) == [("queued", 0), ("running", 1), ("failed", 1)]
    assert reward_rows(stack, job_id) == 0
    return str(failed["error"])


def test_job_over_the_worker_memory_limit_fails_at_once_and_is_not_retried(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    """1 MiB is below any fit's estimate (torch alone needs hundreds): the worker refuses before fitting."""
    error = failure_on_a_worker_with(stack, worker, worker_max_memory_mb=1)
    assert error.startswith("The job needs an estimated ")
    assert "more than the 1 MiB this worker allows (METAIRL_WORKER_MAX_MEMORY_MB)" in error


@pytest.mark.skipif(torch.cuda.is_available(), reason="torch sees a CUDA GPU on this machine")
def test_job_on_a_worker_set_to_cuda_without_a_gpu_fails_at_once_saying_why(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    error = failure_on_a_worker_with(stack, worker, worker_device="cuda")
    assert "(METAIRL_WORKER_DEVICE=cuda) but torch sees no CUDA GPU" in error


def test_a_fit_that_diverges_fails_at_once_saying_which_settings_to_lower(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    """A confidence the config accepts but whose b·Q overflows: the job fails on its first attempt, readable."""
    demonstrator_id, _ = demonstrated_tasks(stack.client, stack.auth)
    job_id = submit(stack.client, stack.auth, demonstrator_id, QUICK | {"confidence": 1e300})["id"]
    failed = wait_for(stack.client, stack.auth, job_id)
    assert (failed["status"], failed["attempts"]) == ("failed", 1), failed
    assert (
        failed["error"].startswith("The fit diverged at step 1")
        and "config.confidence (1e+300)" in failed["error"]
    )


def test_queued_job_whose_message_was_lost_is_sent_again_and_succeeds(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, _ = demonstrated_tasks(client, auth)
    job_id = unsent_job(client.app.state.sessionmaker, demonstrator_id, QUICK)  # type: ignore[attr-defined]
    done = wait_for(client, auth, job_id, timeout=30)
    assert (done["status"], done["attempts"]) == ("succeeded", 1), done
    assert status_events(stack, job_id) == [("queued", 0), ("queued", 0), ("running", 1), ("succeeded", 1)]
    resent = [e for e in all_events(client, auth, job_id) if (e["message"] or "").startswith(RESENT)]
    assert len(resent) == 1 and "1 of 3" in resent[0]["message"]


def test_duplicate_messages_for_a_running_or_finished_job_are_skipped(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, task_ids = demonstrated_tasks(client, auth)
    job_id = submit(client, auth, demonstrator_id, QUICK)["id"]
    queue = CeleryJobQueue(stack.settings)
    queue.enqueue(job_id)  # arrives while the job runs (or after it finished)
    assert wait_for(client, auth, job_id)["status"] == "succeeded"
    queue.enqueue(job_id)  # arrives after it finished

    def skipped() -> int:
        """How often the workers' logs say they skipped a message of this job."""
        return sum(
            log.read_text().count(f"job {job_id} is not queued") for log in stack.workers.logs.glob("*.log")
        )

    deadline = time.monotonic() + 15
    while skipped() < 2:
        assert time.monotonic() < deadline, f"the worker skipped {skipped()} of the 2 duplicate messages"
        time.sleep(0.2)
    assert queue.waiting() == 0
    job = client.get(f"/v1/jobs/{job_id}", headers=auth).json()
    assert (job["status"], job["attempts"]) == ("succeeded", 1)
    assert status_events(stack, job_id) == [("queued", 0), ("running", 1), ("succeeded", 1)]
    assert reward_rows(stack, job_id) == 1 + len(task_ids)


def test_killed_worker_job_is_rerun_by_the_reaper_with_one_result_set(
    stack: Stack, worker: subprocess.Popen[bytes]
) -> None:
    client, auth = stack.client, stack.auth
    demonstrator_id, task_ids = ring_tasks(client, auth)
    stack.workers.kill(worker)
    fresh = stack.workers.start()  # its pool has not imported torch yet: the kill lands early in attempt 1
    job_id = submit(client, auth, demonstrator_id, LONG)["id"]
    wait_for(client, auth, job_id, lambda j: j["status"] == "running")
    # SIGKILL the whole worker: nothing reports; the in-flight message is gone (files), held until the
    # visibility timeout (Redis) or redelivered at once (RabbitMQ) to be skipped: the job is still running.
    stack.workers.kill(fresh)
    assert client.get(f"/v1/jobs/{job_id}", headers=auth).json()["status"] == "running"

    stack.workers.start()
    done = wait_for(client, auth, job_id, timeout=120)
    assert done["status"] == "succeeded", done
    assert done["attempts"] == 2
    assert reward_rows(stack, job_id) == 1 + len(task_ids)
    events = all_events(client, auth, job_id)
    assert status_events(stack, job_id) == [
        ("queued", 0),
        ("running", 1),
        ("queued", 1),
        ("running", 2),
        ("succeeded", 2),
    ]
    requeued = next(e for e in events if e["status"] == "queued" and e["attempt"] == 1)
    assert "stopped sending heartbeats" in requeued["message"]


def test_worker_answers_the_compose_health_check(stack: Stack, worker: subprocess.Popen[bytes]) -> None:
    """docker-compose.yml's worker health check, run natively (remote control exists on Redis and RabbitMQ)."""
    if stack.name == "embedded":
        pytest.skip("the embedded broker has no remote control; compose runs Redis")
    check = subprocess.run(
        [
            sys.executable,
            "-m",
            "celery",
            "-A",
            "worker.celery_app",
            "inspect",
            "ping",
            "--destination",
            f"celery@{socket.gethostname()}",
            "--timeout",
            "5",
        ],
        cwd=REPO,
        env=settings_environment(stack.settings),
        capture_output=True,
        timeout=60,
    )
    assert check.returncode == 0, check.stdout + check.stderr
    assert b"pong" in check.stdout
