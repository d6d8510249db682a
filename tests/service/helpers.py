"""Small factories that create resources over HTTP, for the API tests and for other test packages."""

from __future__ import annotations

from typing import Any

import numpy as np
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_engine.results import Progress
from service.results.rewards import add_reward
from service.store.histories import add_step_history
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job

CORRIDOR_NEXT_STATE = [[0, 1], [0, 2], [1, 2]]
"""A 3-state corridor: action 0 steps left, action 1 steps right (walls keep you in place)."""


PUBLIC_HOOK = "https://93.184.215.14/metairl-hook"
"""A webhook URL on a public address (an IP, so no name lookup is needed to accept it)."""


def created(response: Any, status: int = 201) -> dict[str, Any]:
    """The JSON of a response that must have `status`, with the body in the failure message."""
    assert response.status_code == status, response.text
    body: dict[str, Any] = response.json()
    return body


def make_mdp(client: TestClient, auth: dict[str, str], **overrides: Any) -> dict[str, Any]:
    """A deterministic corridor MDP (3 states × 2 actions, layout 3×1), fields overridable."""
    body = {
        "kind": "explicit",
        "name": "corridor",
        "n_states": 3,
        "n_actions": 2,
        "gamma": 0.9,
        "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
        "layout": {"width": 3, "height": 1},
    } | overrides
    return created(client.post("/v1/mdps", json=body, headers=auth))


def make_demonstrator(client: TestClient, auth: dict[str, str], name: str = "patient 1") -> dict[str, Any]:
    """A demonstrator with a little metadata."""
    return created(
        client.post("/v1/demonstrators", json={"name": name, "metadata": {"age": 40}}, headers=auth)
    )


def make_task(
    client: TestClient, auth: dict[str, str], *, demonstrator_id: str | None = None, mdp_id: str | None = None
) -> dict[str, Any]:
    """A task (creating a demonstrator and a corridor MDP unless given)."""
    demonstrator_id = demonstrator_id or make_demonstrator(client, auth)["id"]
    mdp_id = mdp_id or make_mdp(client, auth)["id"]
    return created(
        client.post(
            f"/v1/demonstrators/{demonstrator_id}/tasks",
            json={"name": "reach", "mdp_id": mdp_id},
            headers=auth,
        )
    )


def add_demonstrations(
    client: TestClient,
    auth: dict[str, str],
    task_id: str,
    trajectories: list[dict[str, list[int]]] | None = None,
) -> dict[str, Any]:
    """Append valid corridor trajectories to a task."""
    trajectories = trajectories or [
        {"states": [0, 1, 2], "actions": [1, 1]},
        {"states": [2, 1], "actions": [0, 0]},
    ]
    return created(
        client.post(f"/v1/tasks/{task_id}/demonstrations", json={"trajectories": trajectories}, headers=auth)
    )


def queued_job(client: TestClient, auth: dict[str, str]) -> str:
    """The id of a job submitted for a new demonstrator's one demonstrated task (queued; no worker runs it)."""
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    return str(
        created(
            client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
        )["id"]
    )


def store_reward(app: FastAPI, *, job_id: str, shape: dict[str, Any]) -> str:
    """A learned-reward row for `job_id`, written straight to the database (no worker needed); its id."""
    with app.state.sessionmaker() as session:
        job = session.get_one(Job, job_id)
        reward = add_reward(
            session,
            job,
            ordinal=0,
            n_actions=shape["n_actions"],
            reward=np.zeros(shape["n_states"], dtype=np.float32),
        )
        session.commit()
        return reward.id


def owned_resource_ids(app: FastAPI, client: TestClient, auth: dict[str, str]) -> dict[str, str]:
    """One resource of every kind in the lab of `auth`, keyed by the path parameter naming it.

    The cross-lab test fills every `/v1` route's path parameters from this; a route with a parameter
    missing here fails that test until a factory is added.
    """
    task = make_task(client, auth)
    batch = add_demonstrations(client, auth, task["id"])
    created(client.put(f"/v1/tasks/{task['id']}/true-reward", json={"values": [0, 0, 1]}, headers=auth), 200)
    ids = {"mdp_id": task["mdp_id"], "demonstrator_id": task["demonstrator_id"], "task_id": task["id"]}
    ids["batch_id"] = batch["id"]
    ids["job_id"] = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )["id"]
    ids["reward_id"] = store_reward(app, job_id=ids["job_id"], shape={"n_states": 3, "n_actions": 2})
    ids["recording_id"] = make_recording(client, auth, make_demonstrator(client, auth)["id"])["id"]
    ids["webhook_id"] = created(client.post("/v1/webhooks", json={"url": PUBLIC_HOOK}, headers=auth))["id"]
    return ids


def store_results(
    app: FastAPI,
    *,
    job_id: str,
    baseline: np.ndarray,
    task_rewards: list[np.ndarray],
    n_actions: int,
    uncertainty: list[np.ndarray] | None = None,
    evidence: list[np.ndarray] | None = None,
    shrinkage: float | None = None,
    sparsity: float | None = None,
) -> list[str]:
    """Mark `job_id` succeeded with these rewards, as the worker would (no worker needed); their ids.

    Rows: the baseline, then one per task of the job in its order, each task with a value function
    (twice its reward) and a uniform policy; ``uncertainty`` and ``evidence``, where given, one array per row;
    a three-step loss history; and the job's ``shrinkage`` λ and ``sparsity`` q.
    """
    with app.state.sessionmaker() as session:
        job = session.get_one(Job, job_id)
        assert len(task_rewards) == len(job.task_ids), (len(task_rewards), job.task_ids)
        ids = []
        for ordinal, values in enumerate([baseline, *task_rewards]):
            task_id = job.task_ids[ordinal - 1] if ordinal else None
            n_states = len(values)
            policy = np.full((n_states, n_actions), 1.0 / n_actions)
            reward = add_reward(
                session,
                job,
                ordinal=ordinal,
                n_actions=n_actions,
                reward=values,
                value=2 * values if task_id else None,
                policy=policy if task_id else None,
                uncertainty=None if uncertainty is None else uncertainty[ordinal],
                evidence=None if evidence is None else evidence[ordinal],
            )
            ids.append(reward.id)
        steps = [
            Progress(step, 3, 1.0 / step, 0.9 / step, 0.1 / step, None, 0.1 * step) for step in (1, 2, 3)
        ]
        add_step_history(session, job_id, job.attempts, steps)
        job.status = JobStatus.SUCCEEDED.value
        job.shrinkage, job.sparsity = shrinkage, sparsity
        session.commit()
        return ids


def fitted_job(
    app: FastAPI,
    client: TestClient,
    auth: dict[str, str],
    *,
    mdp: dict[str, Any],
    demonstrations: dict[str, list[dict[str, list[int]]]],
    rewards: np.ndarray,
    demonstrator: str = "patient 1",
    config: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """A demonstrator with one task per `demonstrations` entry (name → trajectories) in `mdp`, and a job over
    them marked succeeded with ``rewards[0]`` as baseline and ``rewards[1:]`` as task rewards (no worker).

    Returns the ids: ``demonstrator_id``, ``task_ids``, ``job_id`` and ``reward_ids`` (baseline first).
    """
    demonstrator_id = make_demonstrator(client, auth, demonstrator)["id"]
    task_ids = []
    for name, trajectories in demonstrations.items():
        task = created(
            client.post(
                f"/v1/demonstrators/{demonstrator_id}/tasks",
                json={"name": name, "mdp_id": mdp["id"]},
                headers=auth,
            )
        )
        add_demonstrations(client, auth, task["id"], trajectories)
        task_ids.append(task["id"])
    job = created(
        client.post(
            "/v1/jobs",
            json={"demonstrator_id": demonstrator_id, "task_ids": task_ids, "config": config},
            headers=auth,
        ),
        202,
    )
    reward_ids = store_results(
        app, job_id=job["id"], baseline=rewards[0], task_rewards=list(rewards[1:]), n_actions=mdp["n_actions"]
    )
    return {
        "demonstrator_id": demonstrator_id,
        "task_ids": task_ids,
        "job_id": job["id"],
        "reward_ids": reward_ids,
    }


PLATE = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
"""A 40 cm force plate centred on 0 (metres)."""
UNIT = {
    "forward": (0.0, 1.0),
    "forward right": (0.7071, 0.7071),
    "right": (1.0, 0.0),
    "backward right": (0.7071, -0.7071),
    "backward": (0.0, -1.0),
    "backward left": (-0.7071, -0.7071),
    "left": (-1.0, 0.0),
    "forward left": (-0.7071, 0.7071),
}


def cop_rows(
    reach: dict[str, float],
    *,
    repetitions: int = 3,
    rate: float = 50.0,
    seed: int = 0,
    bend: dict[str, float] | None = None,
) -> list[dict[str, Any]]:
    """Hand-made COP samples: per direction (name: peak distance in metres) `repetitions` out-and-back
    movements (0.6 s rest at the centre without instruction, then 1.2 s out and back along the direction with
    a raised-cosine profile, instructed), slightly jittered in reach and sideways; ``bend`` (name: metres)
    shifts a direction's paths sideways by that much at their peak, counter-clockwise when positive."""
    rng = np.random.default_rng(seed)
    rows: list[dict[str, Any]] = []
    t = 0.0
    for name, distance in reach.items():
        ux, uy = UNIT[name]
        for _ in range(repetitions):
            for _ in range(round(0.6 * rate)):
                rows.append({"t": round(t, 4), "x": 0.0, "y": 0.0, "instruction": "rest"})
                t += 1 / rate
            peak = distance * (1 + 0.05 * rng.standard_normal())
            side = 0.004 * rng.standard_normal() + (bend or {}).get(name, 0.0)
            n = round(1.2 * rate)
            for k in range(n):
                a = peak * 0.5 * (1 - np.cos(2 * np.pi * k / n))
                s = side * np.sin(np.pi * k / n)
                rows.append(
                    {
                        "t": round(t, 4),
                        "x": float(a * ux - s * uy),
                        "y": float(a * uy + s * ux),
                        "instruction": name,
                    }
                )
                t += 1 / rate
    for _ in range(round(0.6 * rate)):
        rows.append({"t": round(t, 4), "x": 0.0, "y": 0.0, "instruction": "rest"})
        t += 1 / rate
    return rows


def make_recording(
    client: TestClient,
    auth: dict[str, str],
    demonstrator_id: str,
    reach: dict[str, float] | None = None,
    **options: Any,
) -> dict[str, Any]:
    """Upload `cop_rows(reach)` (default: forward and left, 0.12 m) onto a 10×10 velocity grid; the recording."""
    body = {
        "bounds": PLATE,
        "grid": {"width": 10, "height": 10, "gamma": 0.9},
        "samples": cop_rows(reach or {"forward": 0.12, "left": 0.12}, **options),
    }
    return created(client.post(f"/v1/demonstrators/{demonstrator_id}/recordings", json=body, headers=auth))
