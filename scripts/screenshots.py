"""Regenerate the dashboard's screenshots in docs/: `python -m scripts.screenshots` from the repository root.

Starts `metairl serve` (API and one worker) with its data in a temporary folder, uploads demo data (grid
walkers with 2, 4 and 16 goal tasks), runs a few jobs with different settings, and saves, from the system
chromium at 1366×768: `docs/dashboard.png` (the job list with a filter), `docs/dashboard-run.png` (a run
page with its loss curve) and `docs/dashboard-16-tasks.png` (the results of a 16-task job).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import httpx

from tests.served import REPO, metairl_serve

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page

CHROMIUM = "/usr/bin/chromium"
SIZE = 6
RIGHT, LEFT, UP, DOWN = range(4)
MOVES = {RIGHT: (1, 0), LEFT: (-1, 0), UP: (0, 1), DOWN: (0, -1)}
TERMINAL = {"succeeded", "failed", "cancelled"}
FAST = {"max_steps": 400, "hidden": [16], "tolerance": 0, "patience": 0, "seed": 0, "tabular_choice": False}
"""A fit of these small tasks that takes a few seconds once a worker has it; the networks' method on this
featureless grid (no choice of the tabular solver), so the screenshots show what the method learns."""
DENSE_PROGRESS = {"METAIRL_JOB_EVENT_INTERVAL_S": "0.1", "METAIRL_JOB_HEARTBEAT_S": "0.1"}
"""Progress samples ten times a second, so even a fit of a few seconds draws a curve."""


def step(state: int, action: int) -> int:
    """The deterministic SIZE×SIZE grid: right, left, up (y + 1), down (y − 1), staying put at the walls."""
    x, y = state % SIZE, state // SIZE
    dx, dy = MOVES[action]
    return min(max(y + dy, 0), SIZE - 1) * SIZE + min(max(x + dx, 0), SIZE - 1)


def walk_to(start: int, goal: int) -> dict[str, list[int]]:
    """A shortest walk from ``start`` to ``goal``: sideways first, then up or down."""
    (x, y), (gx, gy) = (start % SIZE, start // SIZE), (goal % SIZE, goal // SIZE)
    actions = [RIGHT if gx > x else LEFT] * abs(gx - x) + [UP if gy > y else DOWN] * abs(gy - y)
    states = [start]
    for action in actions:
        states.append(step(states[-1], action))
    return {"states": states, "actions": actions}


def ok(response: httpx.Response) -> dict[str, Any]:
    """The JSON body of a successful response (else the problem is raised)."""
    response.raise_for_status()
    body: dict[str, Any] = response.json()
    return body


def grid_mdp(http: httpx.Client) -> str:
    """The SIZE×SIZE grid with a layout (so rewards are drawn); its id."""
    n = SIZE * SIZE
    body = {
        "kind": "explicit",
        "name": f"grid {SIZE}×{SIZE}",
        "n_states": n,
        "n_actions": 4,
        "gamma": 0.9,
        "transitions": {
            "kind": "deterministic",
            "next_state": [[step(s, a) for a in range(4)] for s in range(n)],
        },
        "layout": {"width": SIZE, "height": SIZE},
    }
    return str(ok(http.post("/v1/mdps", json=body))["id"])


def goal_demonstrator(http: httpx.Client, mdp_id: str, name: str, n_tasks: int) -> str:
    """A demonstrator with ``n_tasks`` tasks on the grid, task k walking to the k-th of evenly spread goal
    cells from six starts; its id."""
    demonstrator = ok(http.post("/v1/demonstrators", json={"name": name}))
    cells = SIZE * SIZE
    starts = [0, SIZE - 1, cells - SIZE, cells - 1, cells // 2, SIZE + 2]
    for k in range(n_tasks):
        goal = (k * 7 + 3) % cells
        task = ok(
            http.post(
                f"/v1/demonstrators/{demonstrator['id']}/tasks",
                json={"name": f"goal ({goal % SIZE}, {goal // SIZE})", "mdp_id": mdp_id},
            )
        )
        trajectories = [walk_to(s, goal) for s in starts if s != goal]
        ok(http.post(f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": trajectories}))
    return str(demonstrator["id"])


def submit(http: httpx.Client, demonstrator_id: str, config: dict[str, Any]) -> str:
    """POST a job; its id."""
    return str(ok(http.post("/v1/jobs", json={"demonstrator_id": demonstrator_id, "config": config}))["id"])


def wait_for(http: httpx.Client, job_ids: list[str], timeout: float = 600.0) -> None:
    """Poll until every job is final; a failed one is an error."""
    deadline = time.monotonic() + timeout
    for job_id in job_ids:
        while (job := ok(http.get(f"/v1/jobs/{job_id}")))["status"] not in TERMINAL:
            assert time.monotonic() < deadline, f"not finished after {timeout} s: {job}"
            time.sleep(0.3)
        assert job["status"] != "failed", job


def build_demo(http: httpx.Client) -> dict[str, str]:
    """Demonstrators with 2, 4 and 16 tasks and finished jobs with different settings: the ids by role."""
    mdp = grid_mdp(http)
    two = goal_demonstrator(http, mdp, "participant 07", 2)
    four = goal_demonstrator(http, mdp, "participant 12", 4)
    sixteen = goal_demonstrator(http, mdp, "sixteen goals", 16)
    jobs = {
        "two": submit(http, two, FAST),
        "four_l2": submit(http, four, FAST | {"sharing": "l2", "sharing_weight": 2.0}),
        "run": submit(http, four, FAST | {"max_steps": 1500, "learning_rate": 0.005}),
        "sixteen": submit(http, sixteen, FAST),
    }
    wait_for(http, list(jobs.values()))
    return {"mdp": mdp, "two_tasks": two, "four_tasks": four, "sixteen_tasks": sixteen, **jobs}


def open_page(browser: Browser, url: str, key: str) -> Page:
    """The dashboard at 1366×768 with the key pasted and the job list loaded."""
    page = browser.new_page(viewport={"width": 1366, "height": 768})
    page.set_default_timeout(60_000)
    page.goto(f"{url}/ui")
    page.fill("#key-input", key)
    page.click("#key-use")
    page.wait_for_selector("#jobs tr[data-job]")
    return page


def take(browser: Browser, url: str, key: str, demo: dict[str, str], out: Path) -> list[Path]:
    """The three screenshots of the demo into ``out``; their paths."""
    page = open_page(browser, url, key)
    page.select_option("#filter-status", "succeeded")
    page.wait_for_function("() => document.querySelector('#jobs-page').textContent === 'page 1'")
    page.wait_for_timeout(500)
    paths = [out / "dashboard.png", out / "dashboard-run.png", out / "dashboard-16-tasks.png"]
    page.screenshot(path=paths[0])

    page.click(f"tr[data-job='{demo['run']}'] [data-action='run']")
    page.wait_for_selector("#loss-curve path[data-series='loss']")
    page.wait_for_selector("#downloads a[data-download]")
    page.locator("#run").screenshot(path=paths[1])

    page.click(f"tr[data-job='{demo['sixteen']}'] [data-action='results']")
    page.wait_for_selector(f"#results[data-job='{demo['sixteen']}']")
    page.wait_for_function(
        "() => { const imgs = [...document.querySelectorAll('#heatmaps img')];"
        " return document.querySelectorAll('#heatmaps img[data-reward]').length === 17"
        " && imgs.every(i => i.complete && i.naturalWidth > 0); }"
    )
    page.wait_for_function("() => document.querySelectorAll('#key-states table').length === 16")
    page.locator("#results").screenshot(path=paths[2])
    page.close()
    return paths


def main() -> None:
    """Serve, upload the demo, run its jobs and save the screenshots."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=REPO / "docs", help="folder to write the PNGs to")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    with (
        tempfile.TemporaryDirectory() as folder,
        metairl_serve(Path(folder), settings=DENSE_PROGRESS) as served,
    ):
        http = httpx.Client(
            base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60
        )
        demo = build_demo(http)
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
            try:
                for path in take(browser, served.url, served.key, demo, args.out):
                    print(path.relative_to(REPO) if path.is_relative_to(REPO) else path)
            finally:
                browser.close()


if __name__ == "__main__":
    main()
