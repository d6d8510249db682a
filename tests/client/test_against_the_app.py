"""Every method of `Client` and of `AsyncClient`, run against the real app: one lab's whole journey."""

from __future__ import annotations

import asyncio
import csv
import io
import tempfile
from collections.abc import AsyncIterator, Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_client import AsyncClient, Client, ConflictError, NotFoundError, Page
from tests.client.operations import OPERATION_METHODS
from tests.service.helpers import CORRIDOR_NEXT_STATE, PLATE, PUBLIC_HOOK, cop_rows, store_results

ALL_METHODS = {name for names in OPERATION_METHODS.values() for name in names}
CORRIDOR = {
    "kind": "explicit",
    "name": "corridor",
    "n_states": 3,
    "n_actions": 2,
    "gamma": 0.9,
    "transitions": {"kind": "deterministic", "next_state": CORRIDOR_NEXT_STATE},
    "layout": {"width": 3, "height": 1},
}
VELOCITY_GRID = {
    "kind": "grid",
    "name": "plate",
    "width": 10,
    "height": 10,
    "moves": 8,
    "velocity": True,
    "gamma": 0.9,
}


class Recorder:
    """A client that remembers which of its methods were called."""

    def __init__(self, lab: Any):
        self.lab, self.called = lab, set[str]()

    def __getattr__(self, name: str) -> Any:
        self.called.add(name)
        return getattr(self.lab, name)


class Synchronous:
    """An `AsyncClient` driven from synchronous code: each call runs on one event loop; async iterators are
    read to the end and handed back as lists."""

    def __init__(self, lab: AsyncClient, runner: asyncio.Runner):
        self.lab, self.runner = lab, runner

    def __getattr__(self, name: str) -> Any:
        method = getattr(self.lab, name)

        def run(*args: Any, **kwargs: Any) -> Any:
            result = method(*args, **kwargs)
            if isinstance(result, AsyncIterator):
                return self.runner.run(_collect(result))
            return self.runner.run(result)

        return run


async def _collect(items: AsyncIterator[dict[str, Any]]) -> list[dict[str, Any]]:
    """Every item of an async iterator."""
    return [item async for item in items]


class ToTestClient(httpx.AsyncBaseTransport):
    """An async transport that hands each request to the test app's client (which runs the app's lifespan)."""

    def __init__(self, client: TestClient):
        self.client = client

    async def handle_async_request(self, request: httpx.Request) -> httpx.Response:
        body = await request.aread()
        sync_request = httpx.Request(request.method, request.url, headers=request.headers, content=body)
        response = self.client._transport.handle_request(sync_request)
        return httpx.Response(response.status_code, headers=response.headers, content=response.read())


def recording_csv(reach: dict[str, float]) -> bytes:
    """Hand-made centre-of-pressure samples as the CSV a lab uploads."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=["t", "x", "y", "instruction"])
    writer.writeheader()
    writer.writerows(cop_rows(reach))
    return buffer.getvalue().encode()


def ids(items: Iterator[dict[str, Any]] | list[dict[str, Any]]) -> list[str]:
    """The ids of listed resources."""
    return [item["id"] for item in items]


def standing_csv(seed: int) -> bytes:
    """20 s of a quiet-standing COP at 100 Hz (``t,x,y`` in metres): a slow random walk about the centre."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) / 100
    x, y = (np.cumsum(rng.normal(0, 1e-4, (2, t.size)), axis=1) - 5e-3 * np.sin(t)).tolist()
    return ("t,x,y\n" + "".join(f"{a},{b},{c}\n" for a, b, c in zip(t, x, y, strict=True))).encode()


def journey(app: FastAPI, lab: Any) -> None:
    """Call every client method once or more, checking each answer."""
    lab.check_health()
    assert lab.check_ready()["status"] == "ok"

    # MDPs: JSON and .npz, listed a page at a time and iterated across pages.
    mdp_id = lab.create_mdp(CORRIDOR)
    uploaded = lab.upload_mdp(
        name="corridor upload",
        gamma=0.9,
        arrays={"next_state": np.array(CORRIDOR_NEXT_STATE)},
        layout=(3, 1, 1),
    )
    assert lab.get_mdp(mdp_id)["n_states"] == 3
    assert lab.mdp_arrays(uploaded)["next_state"].tolist() == CORRIDOR_NEXT_STATE
    first: Page = lab.list_mdps(limit=1)
    assert len(first.data) == 1 and first.has_more and first.next_cursor
    assert set(ids(lab.iter_mdps(page_size=1))) == {mdp_id, uploaded}

    # Demonstrators, tasks, demonstrations, ground truth.
    dem = lab.create_demonstrator(name="patient 1", metadata={"age": 40})
    assert lab.get_demonstrator(dem)["metadata"] == {"age": 40}
    assert dem in ids(lab.list_demonstrators().data) and dem in ids(lab.iter_demonstrators(page_size=1))
    task = lab.create_task(dem, name="reach", mdp_id=mdp_id)
    spare = lab.create_task(dem, name="spare", mdp_id=mdp_id)
    assert lab.get_task(task)["mdp_id"] == mdp_id
    assert (
        sorted(ids(lab.list_tasks(dem).data))
        == sorted(ids(lab.iter_tasks(dem, page_size=1)))
        == sorted([task, spare])
    )
    batches = [
        lab.add_demonstrations(task, [([0, 1, 2], [1, 1]), (np.array([2, 1]), np.array([0, 0]))]),
        lab.add_demonstrations(task, [([0, 1], [1])]),
    ]
    assert sorted(ids(lab.list_demonstrations(task).data)) == sorted(
        ids(lab.iter_demonstrations(task, page_size=1))
    )
    assert sorted(ids(lab.iter_demonstrations(task))) == sorted(batches)
    lab.put_true_reward(task, np.array([0.0, 0.0, 1.0]))
    truth = lab.get_true_reward(task)
    assert isinstance(truth, np.ndarray) and truth.dtype == np.float64 and truth.tolist() == [0.0, 0.0, 1.0]
    with pytest.raises(NotFoundError):
        lab.get_true_reward(spare)  # none set

    # One batch read back as JSON and as CSV; the CSV uploaded again from bytes and from a file, then removed.
    first_batch = lab.get_demonstrations(task, batches[0])
    assert (first_batch["id"], first_batch["n_trajectories"]) == (batches[0], 2)
    assert first_batch["trajectories"] == [
        {"states": [0, 1, 2], "actions": [1, 1]},
        {"states": [2, 1], "actions": [0, 0]},
    ]
    as_csv = lab.download_demonstrations(task, batches[0])
    assert as_csv.decode().splitlines()[:2] == ["trajectory,step,state,action", "0,0,0,1"]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "batch.csv"
        path.write_bytes(as_csv)
        copies = [lab.upload_demonstrations(spare, as_csv), lab.upload_demonstrations(spare, path)]
    for copy in copies:
        again = lab.get_demonstrations(spare, copy)
        assert (again["format"], again["trajectories"]) == ("csv", first_batch["trajectories"])
        lab.delete_demonstrations(spare, copy)
        with pytest.raises(NotFoundError):
            lab.get_demonstrations(spare, copy)
    assert lab.get_task(spare)["n_trajectories"] == 0

    # Recordings and the motion readout of two demonstrators.
    grid = lab.create_mdp(VELOCITY_GRID)
    walkers = [lab.create_demonstrator(name=f"walker {n}") for n in (1, 2)]
    recordings = [
        lab.upload_recording(
            w, recording_csv({"forward": r, "left": r}), mdp_id=grid, bounds=PLATE, name="trial"
        )
        for w, r in zip(walkers, (0.10, 0.14), strict=True)
    ]
    assert (
        ids(lab.list_recordings(walkers[0]).data)
        == ids(lab.iter_recordings(walkers[0]))
        == [recordings[0]["id"]]
    )
    cut = lab.recording_demonstrations(recordings[0]["id"], label="forward")
    assert cut["recording_id"] == recordings[0]["id"]
    summary = lab.motion_summary(walkers[0])
    assert {d["direction"] for d in summary["directions"]} == {"forward", "left"}
    assert {d["direction"] for d in lab.compare_motion(*walkers)["directions"]} == {"forward", "left"}
    assert lab.compare_motion_png(*walkers).startswith(b"\x89PNG")

    # Quiet standing: two trials labelled by vision, their sway measures, picture and summary.
    stander = lab.create_demonstrator(name="stander")
    trials = [
        lab.upload_recording(stander, standing_csv(seed), protocol="standing", metadata={"vision": vision})
        for seed, vision in enumerate(("open", "closed", "open", "closed"))
    ]
    sway = lab.recording_sway(trials[0]["id"], spectra=True)
    assert sway["recording_id"] == trials[0]["id"] and sway["descriptors"]["area95"] > 0
    assert lab.recording_sway_png(trials[0]["id"], lowpass_hz=10).startswith(b"\x89PNG")
    assert {g["label"] for g in lab.sway_summary(stander, by="vision")["groups"]} == {"open", "closed"}

    # Jobs: one cancelled and deleted, one given results as the worker would.
    cancelled = lab.submit_job(dem, task_ids=[task], config={"max_steps": 5})
    assert lab.get_job(cancelled.id).status == "queued"
    with pytest.raises(ConflictError):
        lab.delete_demonstrations(task, batches[1])  # the queued job will read it
    assert lab.cancel_job(cancelled.id).status == "cancelled"
    with pytest.raises(ConflictError):
        lab.cancel_job(cancelled.id)
    assert (
        len(lab.list_events(cancelled.id).data) == len(list(lab.iter_events(cancelled.id, page_size=1))) >= 1
    )
    assert lab.job_history(cancelled.id)["points"] == []  # it never ran
    lab.delete_job(cancelled.id)
    with pytest.raises(NotFoundError):
        lab.get_job(cancelled.id)
    job = lab.submit_job(dem, task_ids=[task], config={"max_steps": 3})
    assert ids(lab.list_jobs(status="queued").data) == ids(lab.iter_jobs(demonstrator_id=dem)) == [job.id]
    # The job's state carries what the job resource says it fits, with the complete config.
    assert (job.demonstrator_id, job.task_ids, job.config["max_steps"]) == (dem, (task,), 3)
    assert job.config["method"] == "meta_irl" and job.created_at is not None and job.max_attempts
    assert job.body["id"] == job.id and job.loss is None  # no step yet
    baseline, reward = np.array([0.0, 0.5, 1.0]), np.array([1.0, 0.0, 2.0])
    store_results(
        app,
        job_id=job.id,
        baseline=baseline,
        task_rewards=[reward],
        n_actions=2,
        uncertainty=[np.array([0.1, 0.2, 0.3]), np.array([0.3, 0.2, 0.1])],
        evidence=[np.array([1.0, 0.5, 0.0]), np.array([0.0, 0.5, 1.0])],
        shrinkage=0.5,
        sparsity=0.9,
    )
    finished = lab.wait(job.id, progress=False)
    assert (finished.status, finished.shrinkage, finished.sparsity) == ("succeeded", 0.5, 0.9)
    curve = lab.job_history(job.id)
    assert (curve["source"], [p["step"] for p in curve["points"]]) == ("steps", [1, 2, 3])  # every step kept

    # Results.
    rewards = lab.job_rewards(job.id)
    assert list(rewards.tasks) == [task] and rewards.n_states == 3
    assert rewards.truth_pearson[task] == pytest.approx(np.corrcoef(reward, [0.0, 0.0, 1.0])[0, 1])
    learned_baseline, per_task = lab.rewards(job.id)
    assert np.allclose(learned_baseline, baseline) and np.allclose(per_task[task], reward)
    assert np.allclose(lab.reward_values(rewards.tasks[task], quantity="value"), 2 * reward)
    assert lab.download_reward(rewards.baseline, format="csv").decode().startswith("state,")
    assert np.allclose(lab.reward_values(rewards.baseline, quantity="uncertainty"), [0.1, 0.2, 0.3])
    assert np.allclose(lab.reward_values(rewards.tasks[task], quantity="evidence"), [0.0, 0.5, 1.0])
    assert lab.download_reward(rewards.baseline, format="png", quantity="uncertainty").startswith(b"\x89PNG")
    assert lab.reward_png(rewards.baseline).startswith(b"\x89PNG")
    assert lab.compare(rewards.baseline, rewards.tasks[task])["pearson"] == pytest.approx(
        np.corrcoef(baseline, reward)[0, 1]
    )
    assert lab.compare(rewards.tasks[task], task, other_is_task=True)["pearson"] is not None
    assert lab.comparison_matrix(job.id)["reward_ids"] == [rewards.baseline, rewards.tasks[task]]
    assert lab.comparison_matrix_png(job.id).startswith(b"\x89PNG")
    assert len(lab.key_states(rewards.tasks[task], top=2)["states"]) == 2

    # Webhooks.
    hook = lab.create_webhook(PUBLIC_HOOK, events=["job.succeeded"])
    assert hook["secret"] and lab.get_webhook(hook["id"])["events"] == ["job.succeeded"]
    assert ids(lab.list_webhooks().data) == ids(lab.iter_webhooks()) == [hook["id"]]
    lab.delete_webhook(hook["id"])

    # Deleting: a task, then the demonstrator with everything of it, then the MDP nothing uses any more.
    lab.delete_task(spare)
    lab.delete_demonstrator(dem)
    lab.delete_mdp(mdp_id)
    with pytest.raises(NotFoundError):
        lab.get_mdp(mdp_id)


def test_every_client_method_works_against_the_app(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    client.headers.update(auth)
    lab = Recorder(Client(client))
    journey(app, lab)
    assert ALL_METHODS - lab.called == set()


def test_every_async_client_method_works_against_the_app(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    http = httpx.AsyncClient(transport=ToTestClient(client), base_url=str(client.base_url), headers=auth)
    with asyncio.Runner() as runner:
        lab = Recorder(Synchronous(AsyncClient(http), runner))
        journey(app, lab)
        runner.run(http.aclose())
    assert ALL_METHODS - lab.called == set()
