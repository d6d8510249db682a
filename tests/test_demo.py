"""`metairl demo`: experiment generation, client-side scoring, the report files, error formatting, uploads
against the in-process API, and (marked ``worker``) the whole quick demo against a real `metairl serve`."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_cli.demo import API_KEY_ENV, NoLocalKey, resolve_api_key, run_demo, upload_world
from metairl_cli.demo_experiment import (
    QUICK,
    DemoSettings,
    JobOutcome,
    JobPlan,
    goal_excluded_pearson,
    make_experiment,
    plan_jobs,
)
from metairl_cli.demo_report import FIGURE_FILE, HEATMAP_FILES, pearson_figure, summarize, write_report
from metairl_cli.serve import LOCAL_LAB, local_key
from metairl_client import Client, MetairlError
from metairl_engine.metrics import pearson
from service.settings import Settings
from service.store.db import make_engine, migrate
from service.store.models.labs import Lab
from tests.served import free_port, metairl_serve

REPO = Path(__file__).resolve().parents[1]
TINY = dataclasses.replace(
    QUICK, n_worlds=2, size=5, n_hills=2, n_demos=2, task_counts=(1, 3), losses=("none", "huber"), max_steps=5
)
"""An experiment small enough to generate in milliseconds."""
PROBLEM = {
    "type": "/problems/validation",
    "title": "Invalid input",
    "status": 422,
    "detail": "The input is invalid. /transitions/next_state/7/2: must be in 0..8",
    "errors": [
        {"pointer": "/transitions/next_state/7/2", "message": "must be in 0..8, got 9"},
        {"pointer": "", "parameter": "limit", "message": "query parameter limit: too large"},
    ],
}


def test_experiment_has_the_planned_worlds_tasks_demos_and_jobs() -> None:
    worlds = make_experiment(TINY)
    assert [w.index for w in worlds] == [0, 1]
    for sim in worlds:
        assert sim.world.mdp.n_states == 25 and sim.world.mdp.layout is not None
        assert len(sim.tasks) == TINY.n_tasks == 3
        assert len({t.goal for t in sim.tasks}) == 3
        assert all(len(t.trajectories) == 2 and t.true_reward.shape == (25,) for t in sim.tasks)
    assert not np.array_equal(worlds[0].world.cost, worlds[1].world.cost)
    again = make_experiment(TINY)
    assert [t.goal for t in again[1].tasks] == [t.goal for t in worlds[1].tasks]
    plans = plan_jobs(TINY)
    assert len(plans) == 2 * 2 * 2 and len(set(plans)) == len(plans)
    assert {(p.loss, p.n_tasks) for p in plans} == {(x, k) for x in ("none", "huber") for k in (1, 3)}
    assert TINY.job_config("l2") == {"sharing": "l2", "seed": 0, "max_steps": 5}


def test_pearson_leaves_out_the_goal_state() -> None:
    truth = np.random.default_rng(0).normal(size=50)
    learned = truth.copy()
    learned[7] = -100.0  # wrong only at the goal
    assert goal_excluded_pearson(learned, truth, goal=7) == pytest.approx(1.0)
    assert pearson(learned, truth) < 0.5
    assert goal_excluded_pearson(learned, truth, goal=8) < 0.5


def fake_outcomes(settings: DemoSettings, *, noise: float, failed: JobPlan | None = None) -> list[JobOutcome]:
    """Outcomes as if each job returned the true rewards plus noise (more noise with ``none`` sharing)."""
    worlds = make_experiment(settings)
    rng = np.random.default_rng(1)
    out = []
    for plan in plan_jobs(settings):
        if plan == failed:
            out.append(JobOutcome(plan=plan, job_id="job_x", status="failed", error="out of memory"))
            continue
        sim = worlds[plan.world]
        scale = noise * (3.0 if plan.loss == "none" else 1.0)
        truths = np.stack([t.true_reward for t in sim.tasks[: plan.n_tasks]])
        out.append(
            JobOutcome.scored(
                sim,
                plan,
                job_id=f"job_{len(out)}",
                task_ids=tuple(f"task_{i}" for i in range(plan.n_tasks)),
                reward_ids=tuple(f"rwd_{i}" for i in range(plan.n_tasks)),
                baseline_reward_id="rwd_b",
                rewards=truths + rng.normal(scale=scale, size=truths.shape),
                baseline=-sim.world.cost + rng.normal(scale=scale, size=sim.world.cost.shape),
            )
        )
    return out


def test_summary_figure_and_report_files(tmp_path: Path) -> None:
    failed = JobPlan(world=1, loss="huber", n_tasks=3)
    outcomes = fake_outcomes(TINY, noise=0.3, failed=failed)
    cells = {(s.loss, s.n_tasks): s for s in summarize(outcomes)}
    assert set(cells) == {("none", 1), ("none", 3), ("huber", 1), ("huber", 3)}
    assert cells["none", 3].n == 2 and cells["huber", 3].n == 1  # worlds; one huber job failed
    assert cells["huber", 1].mean > cells["none", 1].mean and cells["huber", 1].sd >= 0

    fig = pearson_figure(list(cells.values()), losses=("none", "l2", "huber"), task_counts=TINY.task_counts)
    (ax,) = fig.axes
    assert len(ax.containers) == 2  # l2 has no results: no line
    legend = ax.get_legend()
    assert legend is not None and [t.get_text() for t in legend.get_texts()] == ["none", "huber"]

    table = write_report(tmp_path, TINY, make_experiment(TINY), outcomes)
    for name in (FIGURE_FILE, *HEATMAP_FILES.values(), "results.md", "results.json"):
        assert (tmp_path / name).stat().st_size > 0, name
    assert [row.split("|")[1].strip() for row in table.splitlines()[2:]] == ["none", "huber"]
    markdown = (tmp_path / "results.md").read_text()
    assert table in markdown and "job_x" in markdown and "out of memory" in markdown
    results = json.loads((tmp_path / "results.json").read_text())
    assert len(results["jobs"]) == len(outcomes) and len(results["summary"]) == 4
    assert results["jobs"][0]["pearson"] == list(outcomes[0].pearsons)


def mock_api(handler: Callable[[httpx.Request], httpx.Response]) -> Client:
    """An `Client` whose requests are answered by ``handler``."""
    return Client(httpx.Client(transport=httpx.MockTransport(handler), base_url="http://metairl.test"))


def test_problem_json_becomes_a_readable_service_error() -> None:
    api = mock_api(
        lambda _: httpx.Response(422, json=PROBLEM, headers={"content-type": "application/problem+json"})
    )
    with pytest.raises(MetairlError) as caught:
        api.create_mdp({"kind": "explicit"})
    text = str(caught.value)
    assert text.splitlines()[0] == f"HTTP 422 Invalid input (POST /v1/mdps): {PROBLEM['detail']}"
    assert "  - /transitions/next_state/7/2: must be in 0..8, got 9" in text
    assert "  - limit: query parameter limit: too large" in text
    assert caught.value.status == 422


def test_a_non_json_error_keeps_its_status_and_text() -> None:
    api = mock_api(lambda _: httpx.Response(502, text="upstream down"))
    with pytest.raises(MetairlError, match=r"HTTP 502 Bad Gateway \(GET /v1/jobs/job_1\): upstream down"):
        api.get_job("job_1")


def test_run_demo_prints_the_problem_and_exits_non_zero(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def answer(request: httpx.Request) -> httpx.Response:
        if request.url.path == "/healthz":
            return httpx.Response(200, json={"status": "ok"})
        return httpx.Response(422, json=PROBLEM, headers={"content-type": "application/problem+json"})

    monkeypatch.setattr(Client, "connect", classmethod(lambda cls, **_: mock_api(answer)))
    assert run_demo(url="http://metairl.test", api_key="k", out=str(tmp_path / "out"), quick=True) == 1
    err = capsys.readouterr().err
    assert "Invalid input" in err and "/transitions/next_state/7/2: must be in 0..8, got 9" in err


def test_run_demo_says_when_nothing_answers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    url = f"http://127.0.0.1:{free_port()}"
    assert run_demo(url=url, api_key="k", out=str(tmp_path / "out"), quick=True) == 1
    assert f"cannot reach the service at {url}" in capsys.readouterr().err


def test_upload_and_submit_against_the_api(client: TestClient, api_key: str) -> None:
    client.headers["Authorization"] = f"Bearer {api_key}"
    api = Client(client)
    sim = make_experiment(TINY)[1]
    world = upload_world(api, sim)
    mdp = client.get(f"/v1/mdps/{world.mdp_id}").json()
    assert mdp["n_states"] == 25 and mdp["layout"] == {"width": 5, "height": 5, "channels": 1}
    assert mdp["tabular"] is False
    tasks = client.get(f"/v1/demonstrators/{world.demonstrator_id}/tasks").json()["data"]
    assert sorted(t["id"] for t in tasks) == sorted(world.task_ids)
    assert all(t["n_trajectories"] == 2 and t["has_true_reward"] for t in tasks)
    truth = client.get(f"/v1/tasks/{world.task_ids[0]}/true-reward").json()["values"]
    np.testing.assert_allclose(truth, sim.tasks[0].true_reward, rtol=1e-6)

    job = api.submit_job(world.demonstrator_id, task_ids=world.task_ids[:2], config=TINY.job_config("huber"))
    assert job.status in ("queued", "failed") and not job.step
    stored = client.get(f"/v1/jobs/{job.id}").json()
    assert stored["task_ids"] == list(world.task_ids[:2]) and stored["config"]["sharing"] == "huber"


def test_api_key_comes_from_the_argument_the_environment_or_the_key_serve_keeps(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = Settings(data_dir=tmp_path / "var")
    monkeypatch.setenv(API_KEY_ENV, "from-env")
    assert resolve_api_key("given", settings=settings) == "given"
    assert resolve_api_key(None, settings=settings) == "from-env"
    monkeypatch.delenv(API_KEY_ENV)
    engine = make_engine(settings)  # the data folder as `metairl serve` leaves it: migrated, the key kept
    migrate(engine)
    with Session(engine) as session:
        kept = local_key(session, settings.data_dir)
    assert resolve_api_key(None, settings=settings) == kept
    assert resolve_api_key(None, settings=settings) == kept  # reused, not a new key per run
    with Session(engine) as session:
        assert session.execute(select(Lab.name)).scalars().all() == [LOCAL_LAB]
    engine.dispose()


def test_the_demo_started_away_from_the_data_folder_creates_no_database_and_says_why(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.delenv(API_KEY_ENV, raising=False)
    elsewhere = Settings(data_dir=tmp_path / "var")
    with pytest.raises(NoLocalKey, match=r"no metairl database at .*metairl\.db"):
        resolve_api_key(None, settings=elsewhere)
    monkeypatch.setattr("metairl_cli.demo.get_settings", lambda: elsewhere)
    assert run_demo(url="http://127.0.0.1:9", api_key=None, out=str(tmp_path / "out"), quick=True) == 2
    assert "METAIRL_DATA_DIR" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_the_demo_never_imports_torch() -> None:
    code = "import sys, metairl_cli.demo; print('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[str, str]]:
    """A real `metairl serve` (API + worker) with its data in tmp_path: (URL, API key)."""
    with metairl_serve(tmp_path) as running:
        yield running.url, running.key


@pytest.mark.worker
@pytest.mark.slow
def test_quick_demo_end_to_end(
    served: tuple[str, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url, key = served
    out = tmp_path / "out"
    code = run_demo(url=url, api_key=key, out=str(out), quick=True)
    printed = capsys.readouterr()
    assert code == 0, printed.err
    for name in (FIGURE_FILE, *HEATMAP_FILES.values(), "results.md", "results.json"):
        assert (out / name).stat().st_size > 0, name
    rows = [line for line in (out / "results.md").read_text().splitlines() if line.startswith("| ")]
    for loss in QUICK.losses:
        assert f"| {loss} | " in printed.out
        row = next(r for r in rows if r.startswith(f"| {loss} | "))
        assert "—" not in row, row
    jobs = json.loads((out / "results.json").read_text())["jobs"]
    assert len(jobs) == len(plan_jobs(QUICK)) and all(j["status"] == "succeeded" for j in jobs)
    assert all(len(j["pearson"]) == j["n_tasks"] for j in jobs)
