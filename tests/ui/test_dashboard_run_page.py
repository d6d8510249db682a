"""The dashboard as a run page, in a real browser (the system chromium, driven by Playwright) against a real
`metairl serve`: the loss curve of a job, the job list's filters and paging, download links, heatmaps at full
size, the layout of a 16-task result, submitting a job and deleting resources from the page.

The demo data and jobs are those of `scripts/screenshots.py` (made once for the module). Screenshots go to
`test-artifacts/ui/`.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING
from urllib.parse import urlsplit

import httpx
import pytest

from metairl_engine.grids import DIRECTION_NAMES
from scripts.screenshots import (
    DENSE_PROGRESS,
    FAST,
    build_demo,
    goal_demonstrator,
    grid_mdp,
    submit,
    wait_for,
)
from service.domain.job_config import JobConfig
from tests.served import Served, metairl_serve
from tests.ui.helpers import ARTIFACTS, QUICK, ok, open_dashboard
from tests.ui.test_dashboard_motion_and_webhooks import UNSTIMULATED, recorded

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page, Route

pytestmark = [pytest.mark.worker, pytest.mark.slow, pytest.mark.browser]


@dataclass(frozen=True)
class Demo:
    """A served app with the screenshot script's demo: an HTTP client with the key, and the ids by role."""

    served: Served
    http: httpx.Client
    ids: dict[str, str]


@pytest.fixture(scope="module")
def demo(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Demo]:
    """`metairl serve` (API and worker, progress ten times a second) with the demo's finished jobs."""
    with metairl_serve(tmp_path_factory.mktemp("serve"), settings=DENSE_PROGRESS) as served:
        http = httpx.Client(
            base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60
        )
        yield Demo(served, http, build_demo(http))


@pytest.fixture(scope="module")
def recorded_job(demo: Demo) -> str:
    """A succeeded job of a recorded session on a velocity grid (eight channels, one a direction): its id."""
    session = recorded(demo.http, "recorded session", UNSTIMULATED)
    job_id = submit(demo.http, session, QUICK)
    wait_for(demo.http, [job_id])
    return job_id


def dashboard(browser: Browser, demo: Demo) -> tuple[Page, list[str]]:
    """The page with the key pasted, once the job list has rows."""
    page, errors = open_dashboard(browser, demo.served.url, demo.served.key)
    page.on("dialog", lambda dialog: dialog.accept())  # the confirm before each delete
    page.wait_for_selector("#jobs tr[data-job]")
    return page, errors


def listed(page: Page) -> list[str]:
    """The ids of the job rows shown."""
    return [
        str(i) for i in page.locator("#jobs tr[data-job]").evaluate_all("rs => rs.map(r => r.dataset.job)")
    ]


PULLED = {
    0.0: "every task reward is the baseline",
    0.25: "task rewards pulled three quarters of the way to the baseline",
    0.5: "task rewards pulled half-way to the baseline",
    0.75: "task rewards pulled a quarter of the way to the baseline",
    1.0: "deviations from the baseline kept at full size",
}
"""What the run page says of each shrinkage λ the engine chooses from."""


def test_run_page_draws_the_loss_curve_settings_best_step_shrinkage_and_sparsity_of_a_job(
    demo: Demo, browser: Browser
) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    job_id = demo.ids["run"]
    history = ok(demo.http.get(f"/v1/jobs/{job_id}/history"), 200)
    job = ok(demo.http.get(f"/v1/jobs/{job_id}"), 200)
    assert history["source"] == "steps"  # every step of the fit, not the samples taken while it ran
    assert [p["step"] for p in history["points"]] == list(range(1, job["progress"]["step"] + 1))
    page, errors = dashboard(browser, demo)
    row = page.locator(f"tr[data-job='{job_id}']")
    assert "max_steps=1500" in row.locator("[data-role='config']").inner_text()
    assert row.locator("[data-role='best-step']").inner_text().startswith(str(job["best_step"]))

    row.locator("[data-action='run']").click()
    curve = page.locator(f"#run[data-job='{job_id}'] #loss-curve svg")
    curve.wait_for()
    assert curve.get_attribute("data-points") == str(len(history["points"]))
    assert curve.get_attribute("data-source") == "steps"
    assert (
        page.locator("#loss-curve-source").inner_text()
        == "(every step of the fit, as the engine computed it)"
    )
    series = curve.locator("path").evaluate_all("ps => ps.map(p => p.dataset.series)")
    assert {"loss", "irl_loss", "sharing_loss"} <= set(series)
    assert curve.locator("path[data-series='loss']").evaluate("p => p.getTotalLength()") > 100
    assert curve.locator("[data-role='best-step']").count() == 1
    # Both axes named, a tick mark at each of their numbers; the y axis's name left of its numbers.
    assert curve.locator("[data-role='y-label']").text_content() == "loss"
    assert curve.locator("[data-role='x-label']").text_content() == "step"
    for axis in ("x", "y"):
        marks = curve.locator(f"line.tick-mark[data-axis='{axis}']").count()
        numbers = curve.locator(f"text.tick[data-axis='{axis}']").count()
        assert marks == numbers >= 3, (axis, marks, numbers)
    label = curve.locator("[data-role='y-label']").bounding_box()
    lefts = curve.locator("text.tick[data-axis='y']").evaluate_all(
        "ts => ts.map(t => t.getBoundingClientRect().left)"
    )
    assert label is not None and label["x"] + label["width"] <= min(lefts)
    assert label["height"] > label["width"]  # turned to run along the axis
    shrinkage = job["shrinkage"]
    assert page.locator("#run-facts [data-role='shrinkage']").inner_text() == (
        f"λ {shrinkage:g} ({PULLED[shrinkage]})"
    )
    sparsity = page.locator("#run-facts [data-role='sparsity']").inner_text()
    if job["sparsity"]:
        zeroed = f"the smallest {100 * job['sparsity']:.3g} % of each task's deviations from the baseline"
        assert sparsity == f"q {job['sparsity']:g} ({zeroed} set to zero)"
    else:
        assert sparsity == "q 0 (every state's deviation from the baseline kept)"
    settings = page.locator("#run-config tr[data-setting]").evaluate_all(
        "rs => rs.map(r => r.dataset.setting)"
    )
    assert {"max_steps", "learning_rate", "hidden"} <= set(settings) and "method" not in settings
    page.locator("#run").screenshot(path=ARTIFACTS / "run-page.png")
    assert errors == []


def test_loss_curve_grows_from_the_event_stream_while_a_job_runs(demo: Demo, browser: Browser) -> None:
    job_id = submit(demo.http, demo.ids["four_tasks"], FAST | {"max_steps": 4000})
    page, errors = dashboard(browser, demo)
    page.locator(f"tr[data-job='{job_id}'] [data-action='run']").click()
    page.wait_for_selector(f"#run[data-job='{job_id}'] #loss-curve svg")
    first = int(page.locator("#loss-curve svg").get_attribute("data-points") or 0)
    page.wait_for_function(
        "n => Number(document.querySelector('#loss-curve svg')?.dataset.points) > n + 3", arg=first
    )
    ok(demo.http.post(f"/v1/jobs/{job_id}/cancel"), 202)
    wait_for(demo.http, [job_id])
    assert errors == []


def test_the_curve_of_a_job_that_succeeds_while_shown_becomes_every_step(
    demo: Demo, browser: Browser
) -> None:
    job_id = submit(demo.http, demo.ids["four_tasks"], FAST | {"max_steps": 1500})
    page, errors = dashboard(browser, demo)
    page.locator(f"tr[data-job='{job_id}'] [data-action='run']").click()
    page.wait_for_selector(f"#run[data-job='{job_id}'] #loss-curve svg[data-source='samples']")
    assert "per progress sample" in page.locator("#loss-curve-source").inner_text()
    page.wait_for_selector(f"#run[data-job='{job_id}'] #loss-curve svg[data-source='steps']", timeout=120_000)
    job = ok(demo.http.get(f"/v1/jobs/{job_id}"), 200)
    assert job["status"] == "succeeded"
    curve = page.locator("#loss-curve svg")
    assert curve.get_attribute("data-points") == str(job["progress"]["step"])
    legend = page.locator("#loss-curve .legend [data-series='loss']").inner_text()
    assert legend.endswith(f"{job['progress']['loss']:.3f}")  # the last step's loss
    assert errors == []


def test_a_curve_of_100000_steps_is_drawn_with_a_few_points_a_pixel(demo: Demo, browser: Browser) -> None:
    job_id = demo.ids["run"]
    answer = ok(demo.http.get(f"/v1/jobs/{job_id}/history"), 200)
    n = 100_000
    answer |= {
        "max_steps": n,
        "best_step": n // 2,
        "points": [
            {
                "step": i,
                "loss": 1 / i + (i % 7) * 1e-3,
                "irl_loss": 0.9 / i,
                "sharing_loss": 0.1 / i,
                "heldout_nll": 1 + 1 / i,
                "elapsed_s": i * 1e-3,
            }
            for i in range(1, n + 1)
        ],
    }
    page, errors = dashboard(browser, demo)
    page.route(
        lambda url: url.endswith("/history"),
        lambda route: route.fulfill(status=200, content_type="application/json", body=json.dumps(answer)),
    )
    page.locator(f"tr[data-job='{job_id}'] [data-action='run']").click()
    curve = page.locator(f"#run[data-job='{job_id}'] #loss-curve svg[data-source='steps']")
    curve.wait_for()
    assert curve.get_attribute("data-points") == str(n)
    width = float(curve.get_attribute("width") or 0)
    for series in ("loss", "irl_loss", "sharing_loss", "heldout_nll"):
        d = curve.locator(f"path[data-series='{series}']").get_attribute("d") or ""
        drawn = d.count("L") + 1
        assert 2 * width <= drawn <= 4 * 2 * width, (series, drawn, width)  # every half pixel, at most 4 each
    assert errors == []


def test_every_download_link_answers_200_and_saves_a_file(demo: Demo, browser: Browser) -> None:
    page, errors = dashboard(browser, demo)
    page.locator(f"tr[data-job='{demo.ids['two']}'] [data-action='run']").click()
    page.wait_for_selector("#downloads a[data-download]")
    links = page.locator("#downloads a[data-download]").evaluate_all("as => as.map(a => a.dataset.download)")
    # the baseline's reward, spread and evidence in 4 formats each; per task also value 4 and policy 3; the
    # MDP's arrays
    assert len(links) == 3 * 4 + 2 * (3 * 4 + 4 + 3) + 1, links
    assert any("quantity=policy" in link and "format=npy" in link for link in links)
    assert {"uncertainty", "evidence"} <= {link.partition("quantity=")[2] for link in links}
    assert any(link.endswith("/arrays") for link in links)
    for link in links:
        assert demo.http.get(link).status_code == 200, link
    with page.expect_download() as download:
        page.locator("#downloads a[data-download*='format=csv&quantity=value']").first.click()
    assert download.value.suggested_filename.endswith(".csv")
    assert errors == []


def test_a_recorded_sessions_run_page_links_its_demonstrations_and_each_velocity_channel(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    job_id = recorded_job
    page, errors = dashboard(browser, demo)
    page.locator(f"tr[data-job='{job_id}'] [data-action='run']").click()
    page.wait_for_selector("#downloads tr[data-recording] a[data-download]")
    links = page.locator("#downloads tr[data-recording] a").evaluate_all(
        "as => as.map(a => a.dataset.download)"
    )
    assert len(links) == 2 and links[0].endswith("/demonstrations") and links[1].endswith("?format=csv")
    for link in links:
        response = demo.http.get(link)
        assert response.status_code == 200, link
    assert response.text.startswith("trajectory,step,state,action")
    page.wait_for_function(
        "() => [...document.querySelectorAll('#heatmaps img[data-reward]')].every(i => i.naturalWidth > 0)"
    )
    page.locator("#heatmaps img[data-reward]").nth(1).click()
    assert page.locator("#lightbox-channels button").count() == 1 + 8  # all, and the eight directions
    assert errors == []


def test_results_of_16_tasks_never_overlap_and_a_heatmap_opens_full_size(
    demo: Demo, browser: Browser
) -> None:
    page, errors = dashboard(browser, demo)
    page.locator(f"tr[data-job='{demo.ids['sixteen']}'] [data-action='results']").click()
    page.wait_for_selector(f"#results[data-job='{demo.ids['sixteen']}']")
    page.wait_for_function(
        "() => { const imgs = [...document.querySelectorAll('#heatmaps img[data-reward]')];"
        " return imgs.length === 17 && imgs.every(i => i.complete && i.naturalWidth > 0 && !i.hidden); }"
    )
    page.wait_for_selector("#heatmaps [data-role='placeholder']", state="detached")  # the spreads too
    page.wait_for_function("() => document.querySelectorAll('#key-states table').length === 16")
    boxes = page.evaluate(
        """() => ['#heatmaps', '#matrix table', '#key-states', '.webhooks'].map(s => {
             const r = document.querySelector(s).getBoundingClientRect();
             return {s, left: r.left, right: r.right, top: r.top, bottom: r.bottom}; })"""
    )
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            apart = (
                a["right"] <= b["left"]
                or b["right"] <= a["left"]
                or a["bottom"] <= b["top"]
                or b["bottom"] <= a["top"]
            )
            assert apart, (a, b)
    overflow = page.evaluate(
        "() => document.documentElement.scrollWidth - document.documentElement.clientWidth"
    )
    assert overflow <= 0, "the page scrolls sideways"
    page.screenshot(path=ARTIFACTS / "results-16-tasks.png", full_page=True)

    first = page.locator("#heatmaps img[data-reward]").nth(1)
    shown = first.bounding_box()
    first.click()
    page.wait_for_selector("#lightbox:not([hidden]) #lightbox-img")
    page.wait_for_function("() => document.querySelector('#lightbox-img').naturalWidth > 0")
    big = page.locator("#lightbox-img").bounding_box()
    assert shown is not None and big is not None and big["width"] > shown["width"]
    page.keyboard.press("Escape")
    page.wait_for_selector("#lightbox", state="hidden")
    assert errors == []


def test_a_heatmap_shows_a_placeholder_not_a_broken_image_until_it_has_loaded(
    demo: Demo, browser: Browser
) -> None:
    page, errors = dashboard(browser, demo)
    held: list[Route] = []
    page.route(lambda url: "format=png" in url, lambda route: held.append(route))
    page.locator(f"tr[data-job='{demo.ids['two']}'] [data-action='results']").click()
    page.wait_for_function("() => document.querySelectorAll('#heatmaps img[data-reward]').length === 3")
    pictures = page.locator(
        "#heatmaps img"
    ).count()  # each reward's heatmap and, from an ensemble, its spread
    while len(held) < pictures:
        page.wait_for_timeout(50)
    assert page.locator("#heatmaps [data-role='placeholder']").count() == pictures
    assert (
        page.locator("#heatmaps img[data-reward]:visible").count() == 0
    )  # nothing shown half-loaded or broken
    for route in held:
        route.continue_()
    page.wait_for_selector("#heatmaps [data-role='placeholder']", state="detached")
    assert page.locator("#heatmaps img[data-reward]:visible").count() == 3
    assert errors == []


def two_channel_demonstrator(http: httpx.Client) -> str:
    """A demonstrator with two tasks on a 3×2 grid with two channels (action 0 moves right along the row,
    wrapping; action 1 switches channel); each task walks to one cell of channel 1; its id."""
    width, height, channels = 3, 2, 2
    n = width * height * channels

    def move(s: int, a: int) -> int:
        c, rest = divmod(s, width * height)
        y, x = divmod(rest, width)
        return (1 - c) * width * height + rest if a else c * width * height + y * width + (x + 1) % width

    mdp = ok(
        http.post(
            "/v1/mdps",
            json={
                "kind": "explicit",
                "name": "two channels",
                "n_states": n,
                "n_actions": 2,
                "gamma": 0.9,
                "transitions": {
                    "kind": "deterministic",
                    "next_state": [[move(s, a) for a in (0, 1)] for s in range(n)],
                },
                "layout": {"width": width, "height": height, "channels": channels},
            },
        )
    )
    dem = ok(http.post("/v1/demonstrators", json={"name": "two channels"}))
    for name, goal_x in (("channel 1, x 2", 2), ("channel 1, x 1", 1)):
        task = ok(http.post(f"/v1/demonstrators/{dem['id']}/tasks", json={"name": name, "mdp_id": mdp["id"]}))
        trajectories = []
        for start in range(width):
            actions = [1] + [0] * ((goal_x - start) % width)
            states = [start]
            for a in actions:
                states.append(move(states[-1], a))
            trajectories.append({"states": states, "actions": actions})
        ok(http.post(f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": trajectories}))
    return str(dem["id"])


def test_the_lightbox_draws_one_channel_of_a_reward_at_full_size(demo: Demo, browser: Browser) -> None:
    job_id = submit(demo.http, two_channel_demonstrator(demo.http), FAST)
    wait_for(demo.http, [job_id])
    task = ok(demo.http.get(f"/v1/jobs/{job_id}/rewards"), 200)["tasks"][0]
    values = ok(demo.http.get(f"/v1/rewards/{task['reward_id']}?format=json"), 200)["values"]
    best = max(range(len(values)), key=values.__getitem__)
    channel, rest = divmod(best, 6)
    y, x = divmod(rest, 3)
    page, errors = dashboard(browser, demo)
    page.locator(f"tr[data-job='{job_id}'] [data-action='results']").click()
    page.wait_for_function(
        "() => [...document.querySelectorAll('#heatmaps img[data-reward]')].every(i => i.naturalWidth > 0)"
    )
    page.locator("#heatmaps img[data-reward]").nth(1).click()
    buttons = page.locator("#lightbox-channels button").evaluate_all("bs => bs.map(b => b.dataset.channel)")
    assert buttons == ["all", "0", "1"]
    held: list[Route] = []
    page.route(
        lambda url: f"/v1/rewards/{task['reward_id']}?format=json" in url, lambda route: held.append(route)
    )
    page.click(f"#lightbox-channels button[data-channel='{channel}']")
    while not held:
        page.wait_for_timeout(50)
    assert page.locator("#lightbox-loading").is_visible()  # a sign while the values come
    held[0].continue_()
    canvas = page.locator(f"#lightbox-canvas[data-channel='{channel}']")
    canvas.wait_for()
    page.wait_for_selector("#lightbox-loading", state="hidden")
    size = canvas.evaluate("c => [c.width, c.height]")
    assert size[0] * 2 == size[1] * 3 and size[0] >= 300  # 3×2 cells, enlarged
    # Its axes: named x and y as the server's heatmaps name them, each cell numbered at its centre, y up.
    assert page.locator(".channel-plot [data-role='x-label']").inner_text() == "x"
    assert page.locator(".channel-plot [data-role='y-label']").inner_text() == "y"
    assert page.locator("#lightbox-x-ticks span").all_inner_texts() == ["0", "1", "2"]
    assert page.locator("#lightbox-y-ticks span").all_inner_texts() == ["1", "0"]
    box = canvas.bounding_box()
    first = page.locator("#lightbox-x-ticks span").first.bounding_box()
    bottom = page.locator("#lightbox-y-ticks span").last.bounding_box()
    assert box is not None and first is not None and bottom is not None
    cell = box["width"] / 3
    assert abs(first["x"] + first["width"] / 2 - (box["x"] + cell / 2)) <= 1
    assert abs(bottom["y"] + bottom["height"] / 2 - (box["y"] + box["height"] - cell / 2)) <= 1
    colour = canvas.evaluate(
        "(c, [x, y]) => { const cell = c.width / 3;"
        " return [...c.getContext('2d').getImageData((x + .5) * cell, (1 - y + .5) * cell, 1, 1).data].slice(0, 3); }",
        [x, y],
    )
    assert colour == [253, 231, 37]  # the highest reward, yellow at the top of the colour map
    page.click("#lightbox-channels button[data-channel='all']")
    assert page.locator("#lightbox-img").is_visible() and page.locator("#lightbox-canvas").is_hidden()
    assert errors == []


def test_a_job_submitted_from_the_form_is_created_with_the_settings_typed(
    demo: Demo, browser: Browser
) -> None:
    page, errors = dashboard(browser, demo)
    # The settings show their defaults, from the OpenAPI schema of JobConfig.
    page.click("#submit-settings summary")
    default = JobConfig.model_fields["max_steps"].default
    assert page.locator("#submit-config input[name='max_steps']").get_attribute("placeholder") == str(default)
    page.select_option("#submit-demonstrator", demo.ids["four_tasks"])
    page.locator("#submit-tasks input[name=task]").nth(3).uncheck()
    page.fill("#submit-config input[name='max_steps']", "30")
    page.fill("#submit-config input[name='hidden']", "[8]")
    page.select_option("#submit-config select[name='sharing']", '"l2"')
    before = set(listed(page))
    page.click("#submit-job")
    page.wait_for_function("n => document.querySelectorAll('#jobs tr[data-job]').length > n", arg=len(before))
    (new,) = set(listed(page)) - before
    job = ok(demo.http.get(f"/v1/jobs/{new}"), 200)
    assert job["demonstrator_id"] == demo.ids["four_tasks"] and len(job["task_ids"]) == 3
    assert (
        job["config"]["max_steps"] == 30
        and job["config"]["hidden"] == [8]
        and job["config"]["sharing"] == "l2"
    )
    page.wait_for_selector(f"#run[data-job='{new}']")

    # A bad setting is a problem shown beside the form, naming the field; no job is made.
    page.fill("#submit-config input[name='max_steps']", "-4")
    page.click("#submit-job")
    page.wait_for_selector("#submit-error:not([hidden])")
    assert "max_steps" in page.inner_text("#submit-error")
    wait_for(demo.http, [new])
    assert errors == []


def test_delete_buttons_remove_a_job_an_mdp_a_task_and_a_demonstrator(demo: Demo, browser: Browser) -> None:
    spare_mdp = grid_mdp(demo.http)
    job_id = submit(demo.http, demo.ids["two_tasks"], FAST | {"max_steps": 5})
    wait_for(demo.http, [job_id])
    doomed = goal_demonstrator(demo.http, demo.ids["mdp"], "withdrawn", 2)
    page, errors = dashboard(browser, demo)

    page.locator(f"tr[data-job='{job_id}'] [data-action='delete-job']").click()
    page.wait_for_selector(f"tr[data-job='{job_id}']", state="detached")
    assert demo.http.get(f"/v1/jobs/{job_id}").status_code == 404

    page.locator(f"#mdps [data-mdp='{spare_mdp}'] [data-action='delete-mdp']").click()
    page.wait_for_selector(f"#mdps [data-mdp='{spare_mdp}']", state="detached")
    assert demo.http.get(f"/v1/mdps/{spare_mdp}").status_code == 404

    task = page.locator(f"[data-demonstrator='{doomed}'] li[data-task]").first
    task_id = task.get_attribute("data-task")
    task.locator("[data-action='delete-task']").click()
    page.wait_for_selector(f"li[data-task='{task_id}']", state="detached")
    assert demo.http.get(f"/v1/tasks/{task_id}").status_code == 404

    page.locator(f"[data-demonstrator='{doomed}'] [data-action='delete-demonstrator']").click()
    page.wait_for_selector(f"[data-demonstrator='{doomed}']", state="detached")
    assert demo.http.get(f"/v1/demonstrators/{doomed}").status_code == 404
    assert errors == []


def test_refresh_after_a_job_is_deleted_elsewhere_closes_its_run_page_and_results(
    demo: Demo, browser: Browser
) -> None:
    job_id = submit(demo.http, demo.ids["two_tasks"], FAST | {"max_steps": 5})
    wait_for(demo.http, [job_id])
    page, errors = dashboard(browser, demo)
    row = page.locator(f"tr[data-job='{job_id}']")
    row.locator("[data-action='run']").click()
    page.wait_for_selector(f"#run[data-job='{job_id}'] #loss-curve svg")
    row.locator("[data-action='results']").click()
    page.wait_for_selector(f"#results[data-job='{job_id}'] #heatmaps img[data-reward]")

    assert demo.http.delete(f"/v1/jobs/{job_id}").status_code == 204
    page.click("#refresh")
    page.wait_for_selector(f"tr[data-job='{job_id}']", state="detached")
    page.wait_for_selector("#run", state="hidden")
    page.wait_for_selector("#results", state="hidden")
    assert page.locator("#run[data-job], #results[data-job]").count() == 0
    message = page.locator("#message")
    assert message.inner_text() == f"Deleted elsewhere: job {job_id}; its panels are closed."
    assert "info" in (message.get_attribute("class") or "")
    assert errors == []


def test_a_job_whose_task_rewards_are_the_baseline_says_so_once_above_its_heatmaps(
    demo: Demo, browser: Browser
) -> None:
    job_id = demo.ids["two"]
    page, errors = dashboard(browser, demo)

    def at_lambda_0(route: Route) -> None:  # the job as a fit that kept no deviation would report it
        response = route.fetch()
        body = response.json()
        for job in body.get("data", [body]):
            if job["id"] == job_id:
                job["shrinkage"] = 0.0
        route.fulfill(response=response, json=body)

    open_results(page, demo, job_id)
    heatmaps_loaded(page, 3)
    assert page.locator("#heatmaps [data-role='all-baseline']").count() == 0  # λ as fitted: no note
    page.route(lambda url: re.fullmatch(r"/v1/jobs(/[^/]+)?", urlsplit(url).path) is not None, at_lambda_0)
    page.click("#refresh")
    page.wait_for_selector("#heatmaps [data-role='all-baseline']")
    assert page.locator("#heatmaps [data-role='all-baseline']").count() == 1
    assert page.locator("#heatmaps [data-role='all-baseline']").inner_text().startswith("λ 0:")
    assert errors == []


def test_the_job_form_lists_a_demonstrators_tasks_in_the_order_they_were_made(
    demo: Demo, browser: Browser
) -> None:
    dem_id = demo.ids["four_tasks"]
    tasks = ok(demo.http.get(f"/v1/demonstrators/{dem_id}/tasks"), 200)["data"]
    made = [t["id"] for t in sorted(tasks, key=lambda t: t["created_at"])]
    page, errors = dashboard(browser, demo)
    page.select_option("#submit-demonstrator", dem_id)
    shown = page.locator("#submit-tasks input[name='task']").evaluate_all("xs => xs.map(x => x.value)")
    assert shown == made
    assert errors == []


def test_filters_by_status_and_demonstrator_and_paging_change_the_job_list(
    demo: Demo, browser: Browser
) -> None:
    page, errors = dashboard(browser, demo)
    everything = listed(page)
    assert {demo.ids[k] for k in ("two", "four_l2", "run", "sixteen")} <= set(everything)

    page.select_option("#filter-demonstrator", demo.ids["sixteen_tasks"])
    page.wait_for_function("() => document.querySelectorAll('#jobs tr[data-job]').length === 1")
    assert listed(page) == [demo.ids["sixteen"]]
    page.select_option("#filter-demonstrator", demo.ids["four_tasks"])
    page.select_option("#filter-status", "failed")
    page.wait_for_selector("#jobs-empty:not([hidden])")
    assert listed(page) == []
    page.select_option("#filter-status", "")
    page.select_option("#filter-demonstrator", "")
    page.wait_for_function(
        "n => document.querySelectorAll('#jobs tr[data-job]').length === n", arg=len(everything)
    )

    # Paging: 15 a page, newest first; a second page holds the older jobs and "Newer" returns.
    for _ in range(16 - len(everything)):
        submit(demo.http, demo.ids["two_tasks"], FAST | {"max_steps": 5})
    page.click("#refresh")
    page.wait_for_function("() => !document.querySelector('#jobs-next').disabled")
    first_page = listed(page)
    assert len(first_page) == 15
    page.click("#jobs-next")
    page.wait_for_function("() => document.querySelector('#jobs-page').textContent === 'page 2'")
    page.wait_for_function("() => document.querySelectorAll('#jobs tr[data-job]').length === 1")
    assert not set(listed(page)) & set(first_page)
    page.click("#jobs-prev")
    page.wait_for_function("() => document.querySelectorAll('#jobs tr[data-job]').length === 15")
    assert errors == []


def open_results(page: Page, demo: Demo, job_id: str) -> None:
    """Show a job's results from its row, the job list filtered to its demonstrator (the jobs the module's
    other tests add may have moved the row off the first page)."""
    job = ok(demo.http.get(f"/v1/jobs/{job_id}"), 200)
    page.select_option("#filter-demonstrator", job["demonstrator_id"])
    page.locator(f"tr[data-job='{job_id}'] [data-action='results']").click()


def heatmaps_loaded(page: Page, count: int) -> None:
    """Wait until the results show ``count`` heatmaps, each loaded and shown."""
    page.wait_for_function(
        "n => { const imgs = [...document.querySelectorAll('#heatmaps img[data-reward]')];"
        " return imgs.length === n && imgs.every(i => i.complete && i.naturalWidth > 0 && !i.hidden); }",
        arg=count,
    )


def test_the_lightbox_names_a_velocity_grids_channels_by_direction_and_titles_the_one_drawn(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    page, errors = dashboard(browser, demo)
    open_results(page, demo, recorded_job)
    heatmaps_loaded(page, 4)  # the baseline and three directions
    # Eight small panels in a picture: the card is wide enough for each to be legible at 1366 px.
    shown = page.locator("#heatmaps img[data-reward]").nth(1).bounding_box()
    assert shown is not None and shown["width"] >= 560, shown
    page.locator("#results").screenshot(path=ARTIFACTS / "results-velocity-grid.png")
    page.locator("#heatmaps img[data-reward]").nth(1).click()
    assert page.locator("#lightbox-channels button").all_inner_texts() == ["all channels", *DIRECTION_NAMES]
    # The bar over the picture is opaque: the page's heading never shows through it.
    background = page.locator(".lightbox-bar").evaluate("bar => getComputedStyle(bar).backgroundColor")
    assert background.startswith("rgb("), background
    page.click("#lightbox-channels button[data-channel='2']")
    page.wait_for_selector("#lightbox-canvas[data-channel='2']")
    task = page.locator("#heatmaps figure h4").nth(1).inner_text()
    assert (
        page.locator("#lightbox-channel-title")
        .inner_text()
        .startswith(f"{task} — moving forward · reward from ")
    )
    assert page.locator("#lightbox-channel-title").is_visible()
    page.screenshot(path=ARTIFACTS / "lightbox-one-direction.png")
    page.keyboard.press("Escape")
    page.wait_for_selector("#lightbox", state="hidden")
    assert errors == []


def test_a_heatmap_opens_full_size_from_the_keyboard_and_focus_returns_on_escape(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    page, errors = dashboard(browser, demo)
    open_results(page, demo, recorded_job)
    heatmaps_loaded(page, 4)
    picture = page.locator("#heatmaps img[data-reward]").nth(1)
    # Tab reaches it: it is in the page's tab order, after the row's Results button.
    assert picture.evaluate("img => img.tabIndex") == 0
    picture.focus()
    page.keyboard.press("Enter")
    page.wait_for_selector("#lightbox:not([hidden])")
    assert page.evaluate("() => document.activeElement.id") == "lightbox-close"
    page.keyboard.press("Escape")
    page.wait_for_selector("#lightbox", state="hidden")
    assert picture.evaluate("img => img === document.activeElement")
    page.keyboard.press(" ")
    page.wait_for_selector("#lightbox:not([hidden])")
    page.keyboard.press("Enter")  # on Close
    page.wait_for_selector("#lightbox", state="hidden")
    assert picture.evaluate("img => img === document.activeElement")
    assert errors == []


def test_results_draw_the_heatmaps_without_waiting_for_the_comparison_matrix(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    job_id = recorded_job
    matrix = ok(demo.http.get(f"/v1/jobs/{job_id}/comparison-matrix"), 200)
    matrix["matrix"][0][1] = matrix["matrix"][1][0] = -0.004  # rounds to zero: no "-0.00"
    page, errors = dashboard(browser, demo)
    held: list[Route] = []
    page.route(lambda url: url.split("?")[0].endswith("/comparison-matrix"), lambda route: held.append(route))
    open_results(page, demo, job_id)
    heatmaps_loaded(page, 4)
    page.wait_for_function("() => document.querySelectorAll('#key-states tbody tr').length === 15")
    assert len(held) == 1 and page.locator("#matrix").inner_text() == "Loading…"
    held[0].fulfill(status=200, json=matrix)
    page.wait_for_selector("#matrix table")
    cells = page.locator("#matrix tbody td").all_inner_texts()
    assert cells[1] == cells[4] == "0.00" and not any(c.startswith("-0.00") for c in cells)

    # A matrix that fails says so in its own box; the heatmaps stay.
    open_results(page, demo, demo.ids["four_l2"])
    page.wait_for_function("() => document.querySelectorAll('#heatmaps img[data-reward]').length === 5")
    while len(held) < 2:
        page.wait_for_timeout(50)
    held[1].fulfill(
        status=503, json={"title": "Service Unavailable", "detail": "the matrix is still being computed"}
    )
    page.wait_for_selector("#matrix :text('Unavailable: the matrix is still being computed')")
    assert page.locator("#heatmaps img[data-reward]").count() == 5
    assert errors == []


def test_key_states_name_each_channel_and_say_when_a_task_reward_is_the_baseline(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    tasks = ok(demo.http.get(f"/v1/jobs/{recorded_job}/rewards"), 200)["tasks"]
    answers = {
        t["reward_id"]: ok(demo.http.get(f"/v1/rewards/{t['reward_id']}/key-states?top=5"), 200)
        for t in tasks
    }
    first, second = (answers[t["reward_id"]] for t in tasks[:2])
    first["states"][0]["channel"] = 0  # a state moving right: channel 0, a direction like any other
    second["states"] = []  # a task reward that is the baseline (λ 0): no state departs from it

    def answer(route: Route) -> None:
        reward_id = route.request.url.split("/v1/rewards/")[1].split("/")[0]
        route.fulfill(status=200, json=answers[reward_id])

    page, errors = dashboard(browser, demo)
    page.route(lambda url: "/key-states" in url, answer)
    open_results(page, demo, recorded_job)
    table = page.locator(f"#key-states table[data-task='{first['task_id']}']")
    table.wait_for()
    where = table.locator("[data-role='where']").all_inner_texts()
    expected = [f"{s['x']}, {s['y']} ({DIRECTION_NAMES[s['channel']]})" for s in first["states"]]
    assert where == expected
    same = page.locator(f"#key-states table[data-task='{second['task_id']}']")
    assert (
        same.locator("[data-role='equals-baseline']")
        .inner_text()
        .startswith("This task's reward equals the baseline everywhere")
    )
    assert same.locator("tbody tr").count() == 1  # no list of states that depart by 0
    assert errors == []


def test_the_job_form_takes_yes_no_settings_from_a_list_and_a_list_setting_as_numbers_with_commas(
    demo: Demo, browser: Browser
) -> None:
    page, errors = dashboard(browser, demo)
    sent: list[dict[str, object]] = []

    def hold(route: Route) -> None:
        if route.request.method != "POST":
            route.continue_()
            return
        sent.append(json.loads(route.request.post_data or "{}"))
        route.fulfill(status=422, json={"title": "Unprocessable", "detail": "held by the test"})

    page.route(lambda url: url.split("?")[0].endswith("/v1/jobs"), hold)
    page.click("#submit-settings summary")
    toggle = page.locator("#submit-config select[name='tabular_choice']")
    assert toggle.locator("option").all_inner_texts() == ["true (default)", "false"]
    toggle.select_option("false")
    assert page.locator("#submit-config input[name='hidden']").get_attribute("placeholder") == "100, 50, 25"
    page.fill("#submit-config input[name='hidden']", "8, 8")
    page.fill("#submit-config input[name='baseline_features']", "0 1")
    page.select_option("#submit-demonstrator", demo.ids["two_tasks"])
    page.click("#submit-job")
    page.wait_for_selector("#submit-error:has-text('held by the test')")
    config = sent[0]["config"]
    assert config == {"tabular_choice": False, "hidden": [8, 8], "baseline_features": [0, 1]}, config
    assert errors == []


def sideways_overflow(page: Page) -> int:
    """How many pixels the page is wider than the window (0 or less: no sideways scrolling)."""
    overflow: int = page.evaluate("() => document.scrollingElement.scrollWidth - window.innerWidth")
    return overflow


def test_the_page_fits_1024_and_1280_pixels_wide_and_the_job_list_scrolls_in_its_own_box(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    page, errors = dashboard(browser, demo)
    # Every panel open: a velocity grid's wide heatmaps, its run page, its motion readout, the job form's
    # settings, and the whole job list.
    open_results(page, demo, recorded_job)
    heatmaps_loaded(page, 4)
    page.locator(f"tr[data-job='{recorded_job}'] [data-action='run']").click()
    page.wait_for_selector(f"#run[data-job='{recorded_job}'] #loss-curve svg")
    session = ok(demo.http.get(f"/v1/jobs/{recorded_job}"), 200)["demonstrator_id"]
    page.click(f".dem[data-demonstrator='{session}'] [data-action='motion']")
    page.wait_for_selector(f"#motion[data-demonstrator='{session}'] #kinematics tbody tr")
    page.click("#submit-settings summary")
    page.select_option("#filter-demonstrator", "")
    page.wait_for_function("() => document.querySelectorAll('#jobs tr[data-job]').length > 1")
    for width in (1024, 1280, 1366):
        page.set_viewport_size({"width": width, "height": 800})
        page.wait_for_timeout(300)
        assert sideways_overflow(page) <= 0, f"the page scrolls sideways at {width} px"
        # The job list keeps to its panel, every column in sight: its box needs no scrolling sideways.
        panel, box = page.evaluate(
            "() => [document.querySelector('.jobs'), document.querySelector('.jobs .scroll')]"
            ".map(n => n.getBoundingClientRect().right)"
        )
        assert box <= panel, (width, box, panel)
        room = page.evaluate(
            "() => { const b = document.querySelector('.jobs .scroll'); return b.scrollWidth - b.clientWidth; }"
        )
        assert room <= 0, f"the job list scrolls sideways at {width} px"
        # The velocity grid's wide heatmaps: two a row from 1280 px, each wide enough to read.
        cards = page.locator("#heatmaps figure img[data-reward]").evaluate_all(
            "imgs => imgs.map(i => { const r = i.getBoundingClientRect(); return [Math.round(r.top), r.width]; })"
        )
        if width >= 1280:
            assert cards[0][0] == cards[1][0], (width, cards)
        assert min(w for _, w in cards) >= 540, (width, cards)
        page.screenshot(path=ARTIFACTS / f"layout-{width}.png", full_page=True)
    assert errors == []


def test_every_setting_of_the_job_form_shows_its_whole_name(demo: Demo, browser: Browser) -> None:
    page, errors = dashboard(browser, demo)
    page.click("#submit-settings summary")
    names = page.locator("#submit-config .config-field")
    names.first.wait_for()
    for width in (1024, 1280, 1366):
        page.set_viewport_size({"width": width, "height": 800})
        page.wait_for_timeout(200)
        clipped = names.evaluate_all(
            "fs => fs.filter(f => { const s = f.querySelector('span');"
            " return s.scrollWidth > s.clientWidth || s.getBoundingClientRect().right > f.getBoundingClientRect().right + 0.5; })"
            ".map(f => f.dataset.setting)"
        )
        assert clipped == [], (width, clipped)
    longest = max(JobConfig.model_fields, key=len)
    field = page.locator(f"#submit-config [data-setting='{longest}'] span")
    assert field.inner_text().startswith(longest) and field.is_visible()
    assert errors == []


def test_the_comparison_matrix_names_each_reward_whole_and_shows_its_colour_scale_in_the_figures_colours(
    demo: Demo, browser: Browser
) -> None:
    from matplotlib import colormaps

    job_id = demo.ids["sixteen"]  # 17 rewards: the matrix stacked below the heatmaps, its columns narrow
    matrix = ok(demo.http.get(f"/v1/jobs/{job_id}/comparison-matrix"), 200)
    names = ["baseline", *DIRECTION_NAMES, *(f"{d} again" for d in DIRECTION_NAMES)]
    assert len(names) == len(matrix["labels"])
    matrix["labels"] = names
    matrix["matrix"][0][1:4] = [-0.9, 0.0, 0.45]
    page, errors = dashboard(browser, demo)
    page.route(
        lambda url: url.split("?")[0].endswith("/comparison-matrix"),
        lambda route: route.fulfill(status=200, json=matrix),
    )
    open_results(page, demo, job_id)
    page.wait_for_selector("#matrix table")
    # Every column and row head shows its whole name: nothing cut off, nothing hidden behind an ellipsis.
    for heads, labels in (("#matrix thead th", ["", *names]), ("#matrix tbody th", names)):
        shown = page.locator(heads).evaluate_all(
            "ths => ths.map(t => [t.innerText.replace(/\\s+/g, ' '), t.scrollWidth <= t.clientWidth])"
        )
        assert [text for text, _ in shown] == labels
        assert all(whole for _, whole in shown), [text for text, whole in shown if not whole]
    # The scale beside the colours: -1 to +1, named.
    scale = page.locator("#matrix [data-role='matrix-scale']")
    assert scale.is_visible()
    assert all(part in scale.inner_text() for part in ("Pearson r", "−1", "+1"))
    # The cells in the colours of the server's matrix figure (matplotlib's RdBu_r on -1..1).
    cells = page.locator("#matrix tbody tr").first.locator("td")
    colours = cells.evaluate_all("cs => cs.slice(0, 4).map(c => getComputedStyle(c).backgroundColor)")
    for r, colour in zip(matrix["matrix"][0][:4], colours, strict=True):
        expected = [round(255 * c) for c in colormaps["RdBu_r"]((r + 1) / 2)[:3]]
        got = [int(n) for n in re.findall(r"\d+", colour)[:3]]
        assert all(abs(a - b) <= 3 for a, b in zip(got, expected, strict=True)), (r, got, expected)
    page.locator("#matrix").screenshot(path=ARTIFACTS / "matrix-16-tasks.png")
    assert errors == []


def test_a_rewards_uncertainty_and_evidence_maps_open_full_size_and_close_with_escape_or_a_click(
    demo: Demo, browser: Browser, recorded_job: str
) -> None:
    page, errors = dashboard(browser, demo)
    open_results(page, demo, recorded_job)
    heatmaps_loaded(page, 4)
    page.wait_for_selector("#heatmaps [data-role='placeholder']", state="detached")
    task = page.locator("#heatmaps figure.task h4").first.inner_text()
    for quantity, close in (("uncertainty", "Escape"), ("evidence", "click")):
        small = page.locator(f"#heatmaps figure.task [data-role='{quantity}'] img").first
        shown = small.bounding_box()
        small.click()
        page.wait_for_selector("#lightbox:not([hidden])")
        page.wait_for_function("() => document.querySelector('#lightbox-img').naturalWidth > 0")
        assert page.locator("#lightbox-img").get_attribute("src") == small.get_attribute("src")
        assert page.locator("#lightbox-title").inner_text() == f"{quantity} of {task}"
        assert page.locator("#lightbox-channels").is_hidden()  # one picture: no channels to pick
        big = page.locator("#lightbox-img").bounding_box()
        assert shown is not None and big is not None and big["width"] > shown["width"], (quantity, shown, big)
        if close == "Escape":
            page.keyboard.press("Escape")
        else:
            page.click("#lightbox-img")
        page.wait_for_selector("#lightbox", state="hidden")
    # From the keyboard too, as a heatmap.
    small = page.locator("#heatmaps figure.task [data-role='evidence'] img").first
    small.focus()
    page.keyboard.press("Enter")
    page.wait_for_selector("#lightbox:not([hidden])")
    page.keyboard.press("Escape")
    page.wait_for_selector("#lightbox", state="hidden")
    assert errors == []
