"""The dashboard `GET /ui` in a real browser (the system chromium, driven by Playwright) against a real
`metairl serve` (API and worker): paste a key, see demonstrators and tasks, cancel a running job from the
page, watch a queued job succeed, open its heatmaps, comparison matrix and key states.

Screenshots go to `test-artifacts/ui/` in the repository root (look at them after a change to the page).
The browser fixture is in `conftest.py`, what the dashboard tests share in `helpers.py`.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import httpx
import pytest
from fastapi.testclient import TestClient

from tests.served import REPO, Served, free_port, metairl_serve
from tests.ui.helpers import ARTIFACTS, LAPTOP, QUICK, TERMINAL, ok, open_dashboard, submit

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Route

pytestmark = [pytest.mark.worker, pytest.mark.slow, pytest.mark.browser]

WIDTH, HEIGHT = 5, 5
RIGHT, LEFT, UP, DOWN = range(4)
RING = 150
ENDLESS = {"max_steps": 100_000, "hidden": [16], "sharing": "l2", "tolerance": 0, "patience": 0}
"""On the ring tasks: runs for many seconds (until cancelled), keeping the one worker busy."""


def grid_step(state: int, action: int) -> int:
    """The deterministic 5×5 grid: right, left, up (y + 1), down (y − 1), staying put at the walls."""
    x, y = state % WIDTH, state // WIDTH
    dx, dy = {RIGHT: (1, 0), LEFT: (-1, 0), UP: (0, 1), DOWN: (0, -1)}[action]
    x, y = min(max(x + dx, 0), WIDTH - 1), min(max(y + dy, 0), HEIGHT - 1)
    return y * WIDTH + x


def walk(x: int, sideways: int, steps: int) -> dict[str, list[int]]:
    """From (x, 0): ``sideways`` ``steps`` times, then up to the top row."""
    actions = [sideways] * steps + [UP] * (HEIGHT - 1)
    states = [x]
    for action in actions:
        states.append(grid_step(states[-1], action))
    return {"states": states, "actions": actions}


def make_walker(http: httpx.Client) -> str:
    """A demonstrator with two tasks on a 5×5 grid (reach the top right or the top left corner from the
    bottom row) and their demonstrations; its id."""
    grid = ok(
        http.post(
            "/v1/mdps",
            json={
                "kind": "explicit",
                "name": "grid 5×5",
                "n_states": WIDTH * HEIGHT,
                "n_actions": 4,
                "gamma": 0.9,
                "transitions": {
                    "kind": "deterministic",
                    "next_state": [[grid_step(s, a) for a in range(4)] for s in range(WIDTH * HEIGHT)],
                },
                "layout": {"width": WIDTH, "height": HEIGHT},
            },
        )
    )
    walker = ok(http.post("/v1/demonstrators", json={"name": "participant 07", "metadata": {"age": 31}}))
    for name, trajectories in (
        ("top right", [walk(x, RIGHT, WIDTH - 1 - x) for x in range(WIDTH)]),
        ("top left", [walk(x, LEFT, x) for x in range(WIDTH)]),
    ):
        task = ok(
            http.post(f"/v1/demonstrators/{walker['id']}/tasks", json={"name": name, "mdp_id": grid["id"]})
        )
        ok(http.post(f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": trajectories}))
    return str(walker["id"])


def make_circler(http: httpx.Client) -> str:
    """A demonstrator with two tasks on a ring without a layout (forward, back); its id."""
    ring = ok(
        http.post(
            "/v1/mdps",
            json={
                "kind": "explicit",
                "name": "ring",
                "n_states": RING,
                "n_actions": 2,
                "gamma": 0.9,
                "transitions": {
                    "kind": "deterministic",
                    "next_state": [[(s - 1) % RING, (s + 1) % RING] for s in range(RING)],
                },
            },
        )
    )
    circler = ok(http.post("/v1/demonstrators", json={"name": "ring walker"}))
    for name, action, states in (
        ("forward", 1, list(range(RING))),
        ("back", 0, list(range(RING - 1, -1, -1))),
    ):
        task = ok(
            http.post(f"/v1/demonstrators/{circler['id']}/tasks", json={"name": name, "mdp_id": ring["id"]})
        )
        trajectory = {"states": states, "actions": [action] * (RING - 1)}
        ok(http.post(f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": [trajectory]}))
    return str(circler["id"])


def wait_until_running(http: httpx.Client, job_id: str, timeout: float = 180.0) -> None:
    """Poll until the job runs (the worker's first start imports torch: allow for a loaded machine)."""
    deadline = time.monotonic() + timeout
    while (job := ok(http.get(f"/v1/jobs/{job_id}"), 200))["status"] != "running" or job["progress"] is None:
        assert job["status"] not in TERMINAL, job
        assert time.monotonic() < deadline, f"not running after {timeout} s: {job}"
        time.sleep(0.3)


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    """`metairl serve`: the API and one worker."""
    with metairl_serve(tmp_path) as served:
        yield served


@pytest.fixture
def api_only(tmp_path: Path) -> Iterator[tuple[str, str]]:
    """The API alone (uvicorn, no worker: a submitted job stays queued): (base URL, API key)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
    env["METAIRL_DATA_DIR"] = str(tmp_path / "var")
    made = subprocess.run(
        [sys.executable, "-m", "metairl_cli", "keys", "create", "--lab", "dashboard"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    key = made.stdout.strip().splitlines()[-1]
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    with (tmp_path / "api.log").open("wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "--factory", "service.api.app:create_app", "--port", str(port)],
            cwd=REPO,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    try:
        deadline = time.monotonic() + 60
        while True:
            assert proc.poll() is None, (tmp_path / "api.log").read_text()
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"{url}/healthz").status_code == 200:
                    break
            assert time.monotonic() < deadline, (tmp_path / "api.log").read_text()
            time.sleep(0.2)
        yield url, key
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_dashboard_follows_a_real_job_from_queued_to_succeeded_and_shows_its_rewards(
    served: Served, browser: Browser
) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=30)
    walker_id, circler_id = make_walker(http), make_circler(http)
    blocker = submit(http, circler_id, ENDLESS)
    wait_until_running(http, blocker)
    job_id = submit(http, walker_id, QUICK)  # behind the blocker: the one worker runs one job at a time
    assert ok(http.get(f"/v1/jobs/{job_id}"), 200)["status"] == "queued"

    page, errors = open_dashboard(browser, served.url, served.key)
    # Paste the key: demonstrators with their tasks, and both jobs, appear.
    page.wait_for_selector(f"[data-demonstrator='{walker_id}'] li:has-text('top right')")
    page.wait_for_selector(f"[data-demonstrator='{circler_id}'] li:has-text('back')")
    assert page.evaluate("sessionStorage.getItem('metairl.apiKey')") == served.key
    ours = page.locator(f"tr[data-job='{job_id}']")
    theirs = page.locator(f"tr[data-job='{blocker}']")
    assert ours.get_attribute("data-status") == "queued"
    page.wait_for_function(
        "id => /step \\d+/.test(document.querySelector(`tr[data-job='${id}']`).textContent)", arg=blocker
    )
    assert theirs.get_attribute("data-status") == "running"
    page.screenshot(path=ARTIFACTS / "1-queued-behind-running.png")

    # Cancel the running job from the page; then ours runs, and the page follows it to the end.
    theirs.locator("[data-action='cancel']").click()
    seen = ["queued"]
    deadline = time.monotonic() + 180
    while seen[-1] != "succeeded":
        assert time.monotonic() < deadline, f"the page saw {seen}: {ok(http.get(f'/v1/jobs/{job_id}'), 200)}"
        status = ours.get_attribute("data-status")
        if status != seen[-1]:
            seen.append(str(status))
        assert status not in {"failed", "cancelled"}, ok(http.get(f"/v1/jobs/{job_id}"), 200)
        time.sleep(0.1)
    assert set(seen) <= {"queued", "running", "succeeded"}, seen
    page.wait_for_selector(f"tr[data-job='{blocker}'][data-status='cancelled']")
    assert ours.locator("[role='progressbar']").get_attribute("aria-valuenow") == "100"
    assert re.search(r"attempt 1/\d+ · [\d. min]+ s in all", ours.inner_text()), ours.inner_text()

    # Open the results: three heatmaps (baseline first), the 3×3 matrix, key states of both tasks.
    ours.locator("[data-action='results']").click()
    page.wait_for_selector(f"#results[data-job='{job_id}']")
    page.wait_for_function(
        "() => { const imgs = [...document.querySelectorAll('#heatmaps img[data-reward]')];"
        " return imgs.length === 3 && imgs.every(i => i.complete && i.naturalWidth > 0); }"
    )
    # Beside each reward, the spread of the ensemble's members (a small fit has several) and the evidence.
    for quantity in ("uncertainty", "evidence"):
        page.wait_for_function(
            f"() => {{ const imgs = [...document.querySelectorAll(\"#heatmaps [data-role='{quantity}'] img\")];"
            " return imgs.length === 3 && imgs.every(i => i.complete && i.naturalWidth > 0); }"
        )
    assert page.locator("#heatmaps figure").first.locator(".beside").evaluate_all(
        "boxes => boxes.map(b => b.dataset.role)"
    ) == ["uncertainty", "evidence"]
    # Each drawn at its own aspect, not letterboxed in the reward map's fixed box.
    aspect_errors = page.locator("#heatmaps .beside img").evaluate_all(
        "imgs => imgs.map(i => Math.abs(i.clientHeight / i.clientWidth - i.naturalHeight / i.naturalWidth))"
    )
    assert len(aspect_errors) == 6 and max(aspect_errors) < 0.05, aspect_errors
    kinds = page.locator("#heatmaps figure").evaluate_all("fs => fs.map(f => f.dataset.rewardKind)")
    assert kinds == ["baseline", "task", "task"]
    assert page.locator("#heatmaps img").first.evaluate("img => img.src.startsWith('blob:')")
    # The matrix comes on its own request, after the heatmaps may already show.
    page.wait_for_function("() => document.querySelectorAll('#matrix tbody td').length === 9")
    assert page.locator("#matrix thead th").all_inner_texts()[1:] == ["baseline", "top right", "top left"]
    page.wait_for_function("() => document.querySelectorAll('#key-states tbody tr').length === 10")
    page.screenshot(path=ARTIFACTS / "2-results.png")
    page.screenshot(path=ARTIFACTS / "3-results-full.png", full_page=True)

    # The key stays for the tab: a reload shows the jobs again without pasting it.
    page.reload()
    page.wait_for_selector(f"tr[data-job='{job_id}'][data-status='succeeded']")
    assert errors == []


def sse(*events: tuple[int, str, dict[str, Any]]) -> str:
    """A Server-Sent Events body: (id, event name, JSON data) per event, after a comment line."""
    return ": metairl\n\n" + "".join(
        f"id: {i}\nevent: {name}\ndata: {json.dumps(data)}\n\n" for i, name, data in events
    )


def test_dashboard_reads_the_event_stream_resumes_with_last_event_id_and_stops_at_the_terminal_status(
    api_only: tuple[str, str], browser: Browser
) -> None:
    """The SSE contract of `GET /v1/jobs/{id}/events` (docs/api.md, "Following a job live"), played by the browser's router for a job
    that really stays queued (no worker): progress from the stream, a resume after the stream closed early,
    the end at the terminal status."""
    url, key = api_only
    http = httpx.Client(base_url=url, headers={"Authorization": f"Bearer {key}"}, timeout=30)
    job_id = submit(http, make_walker(http), QUICK)
    progress: dict[str, Any] = {"step": 42, "max_steps": 300, "loss": 0.75, "irl_loss": 0.7}
    progress |= {"sharing_loss": 0.05, "heldout_nll": None, "elapsed_s": 3.5}
    phase = {"running": True}
    streams: list[dict[str, str]] = []
    pending: list[Route] = []

    def events(route: Route) -> None:
        headers = route.request.headers
        streams.append(headers)
        if len(streams) == 1:  # a running job's first events, then the connection drops
            body = sse((1, "status", {"kind": "status", "status": "running"}), (2, "progress", progress))
            route.fulfill(status=200, headers={"Content-Type": "text/event-stream"}, body=body)
        else:  # answered by the test below
            pending.append(route)

    def job(route: Route) -> None:
        """The job as the stream describes it (running at step 42) until the test ends that."""
        if not phase["running"]:
            route.continue_()
            return
        real = ok(http.get(f"/v1/jobs/{job_id}"), 200)
        real |= {"status": "running", "progress": {**progress, "max_steps": 300}, "attempts": 1}
        route.fulfill(status=200, json=real)

    page = browser.new_page(viewport=LAPTOP)
    page.route(lambda u: u.split("?")[0].endswith(f"/v1/jobs/{job_id}/events"), events)
    page.route(lambda u: u.split("?")[0].endswith(f"/v1/jobs/{job_id}"), job)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.set_default_timeout(30_000)
    page.goto(f"{url}/ui")
    page.fill("#key-input", key)
    page.click("#key-use")

    row = page.locator(f"tr[data-job='{job_id}']")
    page.wait_for_selector(f"tr[data-job='{job_id}'][data-status='running']:has-text('step 42 / 300')")
    assert page.locator("#live").inner_text() == "● live (event stream)"
    assert row.locator("[role='progressbar']").get_attribute("aria-valuenow") == "14"
    assert "0.750" in row.inner_text()
    assert "step 42 / 300 · fitting 3.5 s" in row.inner_text()  # the fit's own time, named as such
    deadline = time.monotonic() + 30
    while not pending:
        assert time.monotonic() < deadline, streams
        page.wait_for_timeout(100)
    assert streams[0]["accept"] == "text/event-stream" and "last-event-id" not in streams[0]
    assert streams[1]["last-event-id"] == "2"
    assert streams[1]["authorization"] == f"Bearer {key}"

    ok(http.post(f"/v1/jobs/{job_id}/cancel"), 202)
    phase["running"] = False
    pending.pop().fulfill(
        status=200,
        headers={"Content-Type": "text/event-stream"},
        body=sse((3, "status", {"kind": "status", "status": "cancelled"})),
    )
    page.wait_for_selector(f"tr[data-job='{job_id}'][data-status='cancelled']")
    page.wait_for_timeout(1500)
    assert len(streams) == 2, "no stream is opened again after the terminal status"
    assert row.locator("[data-action='cancel']").count() == 0
    assert errors == []


def test_ui_serves_only_its_own_files_without_a_key_and_stays_out_of_openapi(client: TestClient) -> None:
    page = client.get("/ui")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "default-src 'self'" in page.headers["content-security-policy"]
    assert 'src="ui/app.js"' in page.text
    for name, kind in (("app.js", "text/javascript"), ("app.css", "text/css")):
        asset = client.get(f"/ui/{name}")
        assert asset.status_code == 200 and asset.headers["content-type"].startswith(kind)
        urls = re.findall(r"https?://[^\s\"'`]+", asset.text)
        assert urls in ([], ["http://www.w3.org/2000/svg"]), (
            urls
        )  # nothing from a CDN (a namespace is no fetch)
    assert client.get("/ui/index.py").status_code == 404
    assert client.get("/ui/..%2Fapp.py").status_code == 404
    assert "/ui" not in client.get("/openapi.json").json()["paths"]
