"""What the dashboard tests share: the screenshots' folder, the laptop viewport, HTTP helpers for a served
API, and opening the page with a key."""

from __future__ import annotations

import os
import time
from typing import TYPE_CHECKING, Any

import httpx

from benchmarks.reliability import create_key
from tests.served import REPO, Served

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page, ViewportSize

ARTIFACTS = REPO / "test-artifacts" / "ui"
"""Screenshots (look at them after a change to the page)."""
LAPTOP: ViewportSize = {"width": 1366, "height": 768}
QUICK = {"max_steps": 300, "hidden": [16], "tolerance": 0, "patience": 0, "seed": 0, "tabular_choice": False}
"""A fit of small tasks that takes a second or a few once a worker has it; the networks' method even on the
featureless grids (no choice of the tabular solver), so the page has spreads, shrinkage and a sharing loss
to show."""
TERMINAL = {"succeeded", "failed", "cancelled"}


def ok(response: httpx.Response, status: int = 201) -> dict[str, Any]:
    """The JSON body of a response that must have ``status``."""
    assert response.status_code == status, response.text
    body: dict[str, Any] = response.json()
    return body


def submit(http: httpx.Client, demonstrator_id: str, config: dict[str, Any]) -> str:
    """POST a job; its id."""
    return str(
        ok(http.post("/v1/jobs", json={"demonstrator_id": demonstrator_id, "config": config}), 202)["id"]
    )


def wait_until_succeeded(http: httpx.Client, job_id: str, timeout: float = 180.0) -> None:
    """Poll until the job succeeded (the worker's first start imports torch: allow for a loaded machine)."""
    deadline = time.monotonic() + timeout
    while (job := ok(http.get(f"/v1/jobs/{job_id}"), 200))["status"] != "succeeded":
        assert job["status"] not in TERMINAL, job
        assert time.monotonic() < deadline, f"not finished after {timeout} s: {job}"
        time.sleep(0.3)


def another_labs_key(served: Served, lab: str) -> str:
    """A key of a new lab on the served API (`metairl keys create` on the server's data folder)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
    env["METAIRL_DATA_DIR"] = str(served.log.parent / "var")
    return create_key(env, lab)


def open_dashboard(browser: Browser, url: str, key: str) -> tuple[Page, list[str]]:
    """A laptop-sized page on /ui with the key pasted; and the list its script errors are added to."""
    page = browser.new_page(viewport=LAPTOP)
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.set_default_timeout(60_000)
    page.goto(f"{url}/ui")
    assert page.title() == "metairl dashboard"
    assert page.locator("#main").is_hidden() and page.locator("#welcome").is_visible()  # no key yet
    page.fill("#key-input", key)
    page.click("#key-use")
    return page, errors
