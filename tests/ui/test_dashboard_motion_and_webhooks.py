"""The dashboard's motion readout and webhooks panel in a real browser (the system chromium, driven by
Playwright) against a real `metairl serve` (API and worker; private webhook targets allowed, so the worker
delivers to a receiver in this process): two sessions' recordings read out per direction beside the learned
rewards and compared; a webhook added from the form, its secret shown once, its delivery shown, deleted.

Screenshots go to `test-artifacts/ui/` in the repository root (look at them after a change to the page).
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import TYPE_CHECKING, Any

import httpx
import pytest
from matplotlib.colors import to_rgb

from service.jobs.webhooks import sign
from tests.served import Served, metairl_serve
from tests.service.helpers import PLATE, cop_rows
from tests.ui.helpers import ARTIFACTS, QUICK, ok, open_dashboard, submit, wait_until_succeeded

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page, Route

pytestmark = [pytest.mark.worker, pytest.mark.slow, pytest.mark.browser]

UNSTIMULATED = {"forward": 0.10, "right": 0.10, "left": 0.05}
STIMULATED = {"forward": 0.13, "right": 0.13, "left": 0.08}
"""Peak reach per direction (metres) of one patient's two sessions: stimulation adds 3 cm everywhere."""
Received = list[tuple[dict[str, str], bytes]]


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """`metairl serve`: the API and one worker, accepting webhook targets on this machine."""
    settings = {"METAIRL_WEBHOOK_ALLOW_PRIVATE": "true"}
    with metairl_serve(tmp_path_factory.mktemp("serve"), settings=settings) as served:
        yield served


@contextlib.contextmanager
def receiver() -> Iterator[tuple[str, Received]]:
    """An HTTP server on this machine that answers 204 to every POST: its URL, and the requests it got."""
    got: Received = []

    class Hook(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            body = self.rfile.read(int(self.headers["content-length"]))
            got.append(({k.lower(): v for k, v in self.headers.items()}, body))
            self.send_response(204)
            self.end_headers()

        def log_message(self, format: str, *args: Any) -> None:
            """Quiet."""

    server = ThreadingHTTPServer(("127.0.0.1", 0), Hook)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_port}/hook", got
    finally:
        server.shutdown()
        server.server_close()


def record(
    http: httpx.Client, demonstrator_id: str, name: str, reach: dict[str, float], seed: int = 0
) -> str:
    """Upload a recording (three out-and-back movements per direction of ``reach``) on a 10×10 velocity grid
    to the demonstrator; the recording's id."""
    body = {
        "name": f"{name}, force plate",
        "bounds": PLATE,
        "grid": {"width": 10, "height": 10, "gamma": 0.9},
        "samples": cop_rows(reach, seed=seed),
    }
    return str(ok(http.post(f"/v1/demonstrators/{demonstrator_id}/recordings", json=body))["id"])


def recorded(http: httpx.Client, name: str, reach: dict[str, float], seed: int = 0) -> str:
    """A demonstrator with one recording of ``reach`` (`record`); its id."""
    dem_id = str(ok(http.post("/v1/demonstrators", json={"name": name}))["id"])
    record(http, dem_id, name, reach, seed=seed)
    return dem_id


def directions(page: Page, table: str) -> list[str]:
    """The directions of a readout table's rows, top to bottom."""
    found: list[str] = page.locator(f"{table} tbody tr").evaluate_all(
        "rs => rs.map(r => r.dataset.direction)"
    )
    return found


def test_dashboard_reads_out_a_sessions_motion_beside_its_learned_rewards_and_compares_two_sessions(
    served: Served, browser: Browser
) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    before = recorded(http, "P1 unstimulated", UNSTIMULATED)
    after = recorded(http, "P1 stimulated", STIMULATED, seed=1)
    job_id = submit(http, before, QUICK)
    wait_until_succeeded(http, job_id)
    summary = ok(http.get(f"/v1/demonstrators/{before}/motion-summary"), 200)
    comparison = ok(http.post("/v1/motion-comparisons", json={"a": before, "b": after}), 200)

    page, errors = open_dashboard(browser, served.url, served.key)
    page.click(f"[data-demonstrator='{before}'] [data-action='motion']")
    page.wait_for_selector(f"#motion[data-demonstrator='{before}'] #kinematics tbody tr")
    assert page.locator("#motion-title").inner_text() == "Motion readout of P1 unstimulated"
    assert page.locator(f".dem[data-demonstrator='{before}']").get_attribute("class") == "dem selected"
    # Kinematics: a row per direction as the API orders them, each mean with its interval below.
    assert directions(page, "#kinematics") == [d["direction"] for d in summary["directions"]]
    left = next(d for d in summary["directions"] if d["direction"] == "left")
    cells = page.locator("#kinematics tr[data-direction='left'] td")
    assert cells.nth(0).inner_text() == str(left["n_segments"]) == "3"
    reach = left["peak_reach"]
    assert cells.nth(1).inner_text().split("\n") == [
        f"{reach['mean']:.3f}",
        f"[{reach['low']:.3f}, {reach['high']:.3f}]",
    ]
    assert "x, y units (as uploaded)" in page.locator("#kinematics .units").inner_text()

    # The learned readout of the succeeded job, per direction, with the API's caveat on the baseline.
    page.wait_for_selector("#learned tbody tr")
    assert sorted(directions(page, "#learned")) == sorted(UNSTIMULATED)
    assert job_id in page.locator("#learned .learned-job").inner_text()
    assert "distance from the centre" in page.locator("#learned [data-role='caveat']").inner_text()
    # Path bend needs all eight directions: three give none, shown as a dash.
    assert all(d["path_bend"] is None for d in summary["learned"]["directions"])
    assert page.locator("#learned tr[data-direction='left'] [data-role='path-bend']").inner_text() == "–"
    # Above it, the verdict of the API on it against the recordings, in the API's words.
    verdict = page.locator("#learned [data-role='agreement']")
    assert verdict.get_attribute("data-verdict") == summary["learned"]["agreement"]["verdict"]
    headline, text = verdict.locator("strong").inner_text(), verdict.inner_text()
    detail = summary["learned"]["agreement"]["detail"]
    assert text.count(headline) == 1 and detail.removeprefix(headline).strip() in text  # its words, said once

    # The session comparison: the other recorded demonstrator is b; the figure and b − a per direction.
    assert page.locator("#compare-with").input_value() == after
    page.wait_for_function(
        "() => { const img = document.querySelector('#comparison img');"
        " return img && img.complete && img.naturalWidth > 0; }"
    )
    assert page.locator("#comparison img").evaluate("img => img.src.startsWith('blob:')")
    assert page.locator("#comparison caption").inner_text().startswith("P1 stimulated − P1 unstimulated")
    assert directions(page, "#comparison") == [d["direction"] for d in comparison["directions"]]
    gain = page.locator("#comparison tr[data-direction='left'] td").nth(1)
    assert gain.get_attribute("class") == "num diff pos clear"  # 3 cm more reach, the interval above 0
    diff = next(d for d in comparison["directions"] if d["direction"] == "left")["peak_reach_diff"]
    assert abs(float(gain.inner_text().split("\n")[0]) - diff["mean"]) < 5e-4
    overflow = page.evaluate(
        "() => document.documentElement.scrollWidth - document.documentElement.clientWidth"
    )
    assert overflow <= 0, "the page scrolls sideways"
    page.screenshot(path=ARTIFACTS / "4-motion.png")
    page.screenshot(path=ARTIFACTS / "5-motion-full.png", full_page=True)

    # From the readout to the job's heatmaps: the baseline carries the API's note on velocity grids.
    page.click("#learned [data-action='results']")
    page.wait_for_selector(f"#results[data-job='{job_id}'] figure.baseline [data-role='note']")
    note = page.locator("#heatmaps figure.baseline [data-role='note']")
    note.locator("summary").click()
    assert "distance from the centre" in note.inner_text()
    page.wait_for_function(
        "() => { const imgs = [...document.querySelectorAll('#heatmaps img[data-reward]')];"
        " return imgs.length === 4 && imgs.every(i => i.complete && i.naturalWidth > 0); }"
    )
    assert page.locator("#heatmaps figure.task [data-role='note']").count() == 0
    page.locator("#heatmaps figure.baseline").scroll_into_view_if_needed()
    page.screenshot(path=ARTIFACTS / "6-baseline-note.png")

    # The other session: compared with the first (now b), no learned readout without a job of its own.
    page.click(f"[data-demonstrator='{after}'] [data-action='motion']")
    page.wait_for_selector("#comparison caption:has-text('P1 unstimulated − P1 stimulated')")
    assert page.locator("#compare-with").input_value() == before
    loss = page.locator("#comparison tr[data-direction='left'] td").nth(1)
    assert loss.get_attribute("class") == "num diff neg clear"
    page.wait_for_selector("#learned :text('No job on this demonstrator has succeeded yet')")
    assert page.locator(f".dem[data-demonstrator='{before}']").get_attribute("class") == "dem"
    assert errors == []


def learned_readout(
    served: Served, browser: Browser, name: str
) -> tuple[httpx.Client, str, str, Page, list[str]]:
    """A demonstrator `name` with one recording and a succeeded quick job, its motion readout open on the
    dashboard showing that job: the client, the demonstrator's and job's ids, the page and its errors."""
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    dem_id = recorded(http, name, {"forward": 0.1})
    job_id = submit(http, dem_id, QUICK)
    wait_until_succeeded(http, job_id)
    page, errors = open_dashboard(browser, served.url, served.key)
    page.click(f".dem[data-demonstrator='{dem_id}'] [data-action='motion']")
    page.wait_for_selector(
        f"#motion[data-demonstrator='{dem_id}'] #learned .learned-job:has-text('{job_id}')"
    )
    return http, dem_id, job_id, page, errors


def test_dashboard_says_when_recordings_came_after_the_job_its_learned_readout_shows(
    served: Served, browser: Browser
) -> None:
    http, dem_id, job_id, page, errors = learned_readout(served, browser, "P3 unstimulated")
    assert page.locator("#learned [data-role='stale']").count() == 0  # the fit saw every recording

    later = record(http, dem_id, "P3 unstimulated, again", {"forward": 0.1}, seed=1)
    summary = ok(http.get(f"/v1/demonstrators/{dem_id}/motion-summary"), 200)
    assert summary["learned"]["job_id"] == job_id and summary["learned"]["recordings_after_job"] == [later]
    page.click("#refresh")
    stale = page.locator("#learned [data-role='stale']")
    stale.wait_for()
    assert stale.inner_text().startswith("1 recording(s) came after this job")
    assert "the fit never saw them" in stale.inner_text()
    assert page.locator("#motion-meta").inner_text() == "2 recordings"
    assert errors == []


def standing_only(http: httpx.Client, name: str) -> str:
    """A demonstrator with one quiet-standing trial and no movements; its id."""
    from tests.ui.test_dashboard_sway import standing_trial

    dem_id = str(ok(http.post("/v1/demonstrators", json={"name": name}))["id"])
    body = {"protocol": "standing", "name": f"{name}, eyes open", "samples": standing_trial(0, 0.3)}
    ok(http.post(f"/v1/demonstrators/{dem_id}/recordings", json=body))
    return dem_id


def test_motion_readout_is_offered_for_and_compared_with_recorded_movements_only(
    served: Served, browser: Browser
) -> None:
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    mover = recorded(http, "P5 unstimulated", UNSTIMULATED)
    stander = standing_only(http, "P5 standing")
    page, errors = open_dashboard(browser, served.url, served.key)
    page.wait_for_selector(f".dem[data-demonstrator='{stander}'] [data-action='sway']")
    assert page.locator(f".dem[data-demonstrator='{stander}'] [data-action='motion']").count() == 0

    page.click(f".dem[data-demonstrator='{mover}'] [data-action='motion']")
    page.wait_for_selector(f"#motion[data-demonstrator='{mover}'] #kinematics tbody tr")
    partners = page.locator("#compare-with option").evaluate_all("os => os.map(o => o.value)")
    assert stander not in partners
    for partner in partners:  # each b has movements to compare with
        listing = ok(http.get(f"/v1/demonstrators/{partner}/recordings"), 200)["data"]
        assert any(r["protocol"] == "movements" for r in listing), partner
    assert errors == []


def test_learned_readout_prints_nothing_but_its_parts_under_the_verdict(
    served: Served, browser: Browser
) -> None:
    _, dem_id, _, page, errors = learned_readout(served, browser, "P6 unstimulated")
    page.wait_for_selector(f"#motion[data-demonstrator='{dem_id}'] #learned [data-role='agreement']")
    assert page.locator("#learned [data-role='stale']").count() == 0  # nothing came after the job
    texts = page.locator("#learned").evaluate("box => [...box.childNodes].map(n => n.textContent)")
    assert "null" not in texts and "undefined" not in texts
    assert "null" not in page.locator("#motion").inner_text()
    assert errors == []


def comparison_table(page: Page) -> tuple[list[str], list[list[str]], list[str]]:
    """The session comparison's columns (a descriptor's by its key), its rows' cell texts, and its column
    heads' texts."""
    head = page.locator("#comparison thead th")
    columns: list[str] = head.evaluate_all("ths => ths.map(t => t.dataset.key || t.innerText)")
    rows: list[list[str]] = page.locator("#comparison tbody tr").evaluate_all(
        "rows => rows.map(r => [...r.children].map(c => c.innerText))"
    )
    return columns, rows, head.all_inner_texts()


def rgb(colour: str) -> str:
    """A matplotlib colour as the browser computes a CSS colour: ``rgb(r, g, b)``."""
    r, g, b = (round(255 * c) for c in to_rgb(colour))
    return f"rgb({r}, {g}, {b})"


def test_the_session_comparison_shows_sub_millimetre_differences_with_units_in_the_figures_colours(
    served: Served, browser: Browser
) -> None:
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    a = recorded(http, "P7 unstimulated", UNSTIMULATED)
    b = recorded(http, "P7 stimulated", STIMULATED, seed=1)
    comparison = ok(http.post("/v1/motion-comparisons", json={"a": a, "b": b}), 200)
    assert comparison["unit"] is None  # uploaded without `units`: lengths as uploaded
    # One direction's deviation changes by 0.6 mm of a metre, another by centimetres; a mean of -0, and an
    # interval whose upper end is rounding noise (so it is not marked as leaving out 0).
    comparison["directions"][0]["deviation_diff"] |= {"mean": -6.11e-4, "low": -1.2e-3, "high": 2.5e-4}
    comparison["directions"][1]["deviation_diff"] |= {"mean": 0.0312, "low": 0.011, "high": 0.052}
    comparison["directions"][2]["deviation_diff"] |= {"mean": -1e-9, "low": -0.013, "high": -1e-9}
    comparison["directions"][0]["peak_reach_diff"] |= {
        "mean": -0.02,
        "low": -0.03,
        "high": -0.01,
    }  # less reach
    answer_with: dict[str, str | None] = {"unit": None}

    def answer(route: Route) -> None:
        if "format=png" in route.request.url:
            route.continue_()
            return
        body = json.loads(json.dumps(comparison))
        if answer_with["unit"] == "m":  # the same recordings uploaded with `units` m
            body["unit"] = "m"
            body["units"] |= {"peak_reach": "m", "path_length": "m", "deviation": "m"}
            body["units"]["mean_speed"] = "m per t unit"
        route.fulfill(status=200, json=body)

    page, errors = open_dashboard(browser, served.url, served.key)
    page.route(lambda url: url.split("?")[0].endswith("/v1/motion-comparisons"), answer)
    page.click(f".dem[data-demonstrator='{a}'] [data-action='motion']")
    page.select_option("#compare-with", b)
    page.wait_for_selector(f"#comparison[data-b='{b}'] caption:has-text('P7 stimulated − P7 unstimulated')")
    columns, rows, heads = comparison_table(page)
    deviation = columns.index("deviation")
    assert heads[deviation] == "Δ deviation\n(x, y units)"
    # Without a unit: decimals enough for the smallest difference that is not noise, one format a column.
    assert [row[deviation].split("\n")[0] for row in rows[:3]] == ["-0.00061", "0.03120", "0.00000"]
    assert rows[2][deviation].split("\n")[1] == "[-0.01300, 0.00000]"
    marked = page.locator("#comparison tbody tr").evaluate_all(
        f"rows => rows.map(r => r.children[{deviation}].className)"
    )
    assert marked[:3] == ["num diff", "num diff pos clear", "num diff"]
    for k in range(2, len(columns)):  # every column: one number of decimals throughout, no exponents
        numbers = [
            n for row in rows for n in row[k].replace("[", " ").replace("]", " ").replace(",", " ").split()
        ]
        decimals = {len(n.split(".")[1]) if "." in n else 0 for n in numbers}
        assert len(decimals) == 1 and not any("e" in n for n in numbers), (columns[k], numbers)

    # The figure's colours: red where the interval leaves out 0 (either sign), grey where it holds 0, and
    # each side's colour beside its name.
    cells = page.locator(f"#comparison tbody tr td:nth-child({deviation + 1})")
    colours = cells.evaluate_all("cs => cs.map(c => getComputedStyle(c).color)")
    assert colours[0] == colours[2] == rgb("0.4") and colours[1] == rgb("tab:red")
    for side_of_0 in ("pos", "neg"):
        clear = page.locator(f"#comparison td.{side_of_0}.clear")
        assert clear.count() > 0, side_of_0
        assert set(clear.evaluate_all("cs => cs.map(c => getComputedStyle(c).color)")) == {rgb("tab:red")}
    sides = page.locator("#comparison caption .side i").evaluate_all(
        "is => is.map(i => [i.parentNode.dataset.side, getComputedStyle(i).backgroundColor])"
    )
    assert sorted(sides) == [["a", rgb("tab:blue")], ["b", rgb("tab:orange")]]

    # In metres: lengths under a metre in millimetres, named so; sub-millimetre differences read.
    answer_with["unit"] = "m"
    page.click("#refresh")
    page.wait_for_selector("#comparison thead th[data-key='deviation'] :text('(mm)')")
    columns, rows, heads = comparison_table(page)
    assert heads[columns.index("deviation")] == "Δ deviation\n(mm)"
    assert heads[columns.index("mean_speed")] == "Δ mean speed\n(mm per t unit)"
    assert heads[columns.index("time_to_peak_s")].startswith("Δ time to peak\n(")
    assert "mm" not in heads[columns.index("time_to_peak_s")]
    assert [row[deviation].split("\n")[0] for row in rows[:3]] == ["-0.61", "31.20", "0.00"]
    assert rows[0][deviation].split("\n")[1] == "[-1.20, 0.25]"
    assert errors == []


def test_a_late_answer_for_a_session_no_longer_picked_is_never_shown(
    served: Served, browser: Browser
) -> None:
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    a = recorded(http, "P8 unstimulated", UNSTIMULATED)
    left_behind = recorded(http, "P8 stimulated", STIMULATED, seed=1)
    picked = recorded(http, "P8 follow-up", STIMULATED, seed=2)
    held: list[Route] = []

    def hold(route: Route) -> None:
        """The comparison with ``left_behind`` waits for the test; the others are answered."""
        body = json.loads(route.request.post_data or "{}")
        if "format=png" not in route.request.url and body.get("b") == left_behind:
            held.append(route)
        else:
            route.continue_()

    page, errors = open_dashboard(browser, served.url, served.key)
    page.route(lambda url: url.split("?")[0].endswith("/v1/motion-comparisons"), hold)
    aborted: list[str] = []
    page.on("requestfailed", lambda request: aborted.append(request.post_data or ""))
    page.click(f".dem[data-demonstrator='{a}'] [data-action='motion']")
    page.wait_for_selector(f"#motion[data-demonstrator='{a}'] #kinematics tbody tr")
    page.select_option("#compare-with", left_behind)
    while not held:
        page.wait_for_timeout(50)
    page.select_option("#compare-with", picked)
    page.wait_for_selector(
        f"#comparison[data-b='{picked}'] caption:has-text('P8 follow-up − P8 unstimulated')"
    )
    # The page gave up the earlier request once the pick changed.
    deadline = time.monotonic() + 30
    while not any(left_behind in body for body in aborted):
        assert time.monotonic() < deadline, aborted
        page.wait_for_timeout(50)
    from playwright.sync_api import Error as PlaywrightError

    # The earlier pick's answer comes late, and it is an error: nothing of it shows.
    with contextlib.suppress(PlaywrightError):  # the page may have aborted the request already
        held[0].fulfill(status=404, json={"title": "Not Found", "detail": "answered after the pick changed"})
    page.wait_for_timeout(1000)
    assert page.locator("#message").is_hidden(), page.locator("#message").inner_text()
    assert "after the pick changed" not in page.locator("#motion").inner_text()
    assert page.locator("#comparison caption").inner_text().startswith("P8 follow-up − P8 unstimulated")
    assert page.locator("#comparison").get_attribute("data-b") == picked
    assert errors == []


def test_dashboard_adds_a_webhook_shows_its_secret_once_and_its_delivery_and_deletes_it(
    served: Served, browser: Browser
) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    with receiver() as (hook_url, got):
        page, errors = open_dashboard(browser, served.url, served.key)
        page.context.grant_permissions(["clipboard-read", "clipboard-write"], origin=served.url)
        panel = page.locator("section.webhooks")
        # A URL the API refuses: its reason shows under the form, nothing is added.
        page.fill("#webhook-url", "ftp://lab.example.org/hook")
        page.click("#webhook-add")
        page.wait_for_selector("#webhook-error:has-text('http:// or https://')")
        assert "422" in page.locator("#webhook-error").inner_text()
        assert ok(http.get("/v1/webhooks"), 200)["data"] == []

        page.fill("#webhook-url", hook_url)
        page.uncheck("input[name='events'][value='job.cancelled']")
        page.click("#webhook-add")
        row = page.locator("#webhooks tr[data-webhook]")
        page.wait_for_selector(f"#webhooks tr[data-webhook]:has-text('{hook_url}')")
        assert page.locator("#webhook-error").is_hidden() and page.locator("#webhook-url").input_value() == ""
        secret = page.locator("[data-role='secret']").inner_text()
        assert secret.startswith("whsec_")
        hook_id = row.get_attribute("data-webhook")
        listed = ok(http.get("/v1/webhooks"), 200)["data"]
        assert [(h["id"], h["url"], h["events"]) for h in listed] == [
            (hook_id, hook_url, ["job.failed", "job.succeeded"])
        ]
        assert secret not in json.dumps(listed)
        assert "succeeded, failed" in row.inner_text() and "no deliveries yet" in row.inner_text()
        page.click("[data-action='copy-secret']")
        page.wait_for_selector("[data-action='copy-secret']:has-text('Copied')")
        assert page.evaluate("navigator.clipboard.readText()") == secret
        panel.scroll_into_view_if_needed()
        page.screenshot(path=ARTIFACTS / "7-webhook-secret.png")

        # A job ends: the receiver gets it signed with that secret, and the page shows the delivery.
        job_id = submit(http, recorded(http, "P2 unstimulated", {"forward": 0.1}), QUICK)
        wait_until_succeeded(http, job_id)
        deadline = time.monotonic() + 60
        while (deliveries := ok(http.get(f"/v1/webhooks/{hook_id}"), 200)["deliveries"]) == [] or deliveries[
            0
        ]["status"] != "delivered":
            assert time.monotonic() < deadline, deliveries
            time.sleep(0.3)
        headers, body = got[0]
        assert json.loads(body)["type"] == "job.succeeded" and json.loads(body)["data"]["id"] == job_id
        stamp = int(headers["webhook-timestamp"])
        assert headers["webhook-signature"] == sign(
            secret, msg_id=headers["webhook-id"], timestamp=stamp, body=body
        )
        page.click("#refresh")
        page.wait_for_selector(f"tr[data-webhook='{hook_id}'] [data-role='delivery']:has-text('delivered')")
        assert "job.succeeded" in row.inner_text()

        # The secret goes with "Done" and never comes back: not after a reload either.
        page.click("[data-action='dismiss-secret']")
        assert page.locator("#webhook-secret").is_hidden()
        page.reload()
        page.wait_for_selector(f"tr[data-webhook='{hook_id}'] [data-role='delivery']:has-text('delivered')")
        assert secret not in page.content()
        panel.scroll_into_view_if_needed()
        page.screenshot(path=ARTIFACTS / "8-webhook-delivered.png")

        # Delete asks first: declined, it stays; accepted, it is gone from the page and the API.
        page.once("dialog", lambda dialog: dialog.dismiss())
        page.click(f"tr[data-webhook='{hook_id}'] [data-action='delete']")
        page.wait_for_timeout(500)
        assert row.count() == 1
        page.once("dialog", lambda dialog: dialog.accept())
        page.click(f"tr[data-webhook='{hook_id}'] [data-action='delete']")
        page.wait_for_selector(f"tr[data-webhook='{hook_id}']", state="detached")
        assert page.locator("#webhooks-empty").is_visible()
        assert ok(http.get("/v1/webhooks"), 200)["data"] == []
    assert errors == []
