"""The dashboard's quiet-standing panel in a real browser (the system chromium, driven by Playwright) against
a real `metairl serve`: a demonstrator's standing trials, one trial's sway measures and COP picture, and its
trials compared by vision with the Romberg quotient. Screenshots go to `test-artifacts/ui/`."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import httpx
import numpy as np
import pytest

from tests.served import Served, metairl_serve
from tests.shared_data import shared_data
from tests.ui.helpers import ARTIFACTS, another_labs_key, ok, open_dashboard
from tests.ui.test_dashboard_motion_and_webhooks import record

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Page, Route

pytestmark = [pytest.mark.slow, pytest.mark.browser]


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """`metairl serve`: the API (and its worker, unused here)."""
    with metairl_serve(tmp_path_factory.mktemp("serve")) as served:
        yield served


def standing_trial(seed: int, spread_cm: float, n: int = 1000) -> list[dict[str, float]]:
    """`n` samples at 50 Hz (20 s by default) of a COP wandering about a point, in cm."""
    rng = np.random.default_rng(seed)
    xy = np.zeros((n, 2))
    for k in range(1, n):
        xy[k] = 0.97 * xy[k - 1] + rng.normal(0, spread_cm * 0.2, 2)
    return [{"t": k / 50, "x": float(x), "y": float(y)} for k, (x, y) in enumerate(xy)]


def test_dashboard_shows_a_standing_trials_sway_and_its_picture_and_compares_vision(
    served: Served, browser: Browser
) -> None:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    dem = ok(http.post("/v1/demonstrators", json={"name": "balance subject"}))
    ids = []
    for k, (vision, spread) in enumerate([("open", 0.3), ("open", 0.35), ("closed", 0.5), ("closed", 0.6)]):
        body = {
            "protocol": "standing",
            "name": f"trial {k + 1}",
            "units": "cm",
            "metadata": {"vision": vision},
            "samples": standing_trial(k, spread, n=500 if k == 0 else 1000),  # the first 10 s
        }
        ids.append(ok(http.post(f"/v1/demonstrators/{dem['id']}/recordings", json=body))["id"])
    sway = ok(http.get(f"/v1/recordings/{ids[-1]}/sway"), 200)  # newest first: the panel opens on it
    summary = ok(http.get(f"/v1/demonstrators/{dem['id']}/sway-summary?by=vision"), 200)

    page, errors = open_dashboard(browser, served.url, served.key)
    page.click(f"[data-demonstrator='{dem['id']}'] [data-action='sway']")
    page.wait_for_selector(f"#sway[data-demonstrator='{dem['id']}'] .sway-measures tr[data-measure='area95']")
    assert page.locator("#sway-title").inner_text() == "Quiet standing of balance subject"
    area = page.locator(".sway-measures tr[data-measure='area95'] td")
    assert (
        area.nth(0).inner_text() == f"{sway['descriptors']['area95']:.3f}"
        and area.nth(1).inner_text() == "cm²"
    )
    page.wait_for_function(
        "() => { const img = document.querySelector('#sway-picture img');"
        " return img && img.complete && img.naturalWidth > 0; }"
    )
    page.wait_for_selector(".sway-groups tr[data-group='romberg']")
    # The rate as recorded, without padding zeros (a plate's 99.9987 Hz keeps its digits).
    assert page.locator("#sway .sub").inner_text() == "1000 samples at 50 Hz over 20.000 s"
    romberg = page.locator(".sway-groups tr[data-group='romberg'] td").nth(0).inner_text().split("\n")[0]
    assert romberg == f"{summary['romberg']['area95']['value']:.3f}"
    assert page.locator(".sway-groups tbody tr").count() == 3  # closed, open, Romberg
    page.select_option("#sway-recording", ids[0])
    first = ok(http.get(f"/v1/recordings/{ids[0]}/sway"), 200)["descriptors"]["area95"]
    page.wait_for_selector(f"#sway-picture img[data-recording='{ids[0]}']")
    page.wait_for_function(
        f"() => document.querySelector(\".sway-measures tr[data-measure='area95'] td\")?.textContent === '{first:.3f}'"
    )
    page.wait_for_function(
        "() => { const img = document.querySelector('#sway-picture img');"
        " return img && img.complete && img.naturalWidth > 0; }"
    )
    # A 10-s trial: its frequencies carry the API's caveat, starred, the reason under the table.
    assert (
        page.locator(".sway-measures tr[data-measure='mean_frequency'] td").nth(0).inner_text().endswith(" *")
    )
    reason = ok(http.get(f"/v1/recordings/{ids[0]}/sway"), 200)["caveats"]["mean_frequency"]
    assert page.locator("[data-role='sway-caveat']").inner_text() == f"* {reason}"
    page.locator("#sway").scroll_into_view_if_needed()
    page.screenshot(path=ARTIFACTS / "9-sway.png")
    assert errors == []


def test_dashboard_says_when_a_plate_files_cop_leaves_its_plate(served: Served, browser: Browser) -> None:
    http = httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)
    dem = ok(http.post("/v1/demonstrators", json={"name": "gait subject"}))
    data = (shared_data("c3d") / "others__Gait.c3d").read_bytes()
    rec = ok(
        http.post(
            f"/v1/demonstrators/{dem['id']}/recordings",
            files={"file": ("gait.c3d", data)},
            data={"protocol": "standing"},
        )
    )
    caveat = ok(http.get(f"/v1/recordings/{rec['id']}/sway"), 200)["caveats"]["samples"]
    page, errors = open_dashboard(browser, served.url, served.key)
    page.click(f"[data-demonstrator='{dem['id']}'] [data-action='sway']")
    page.wait_for_selector("[data-role='sway-samples-caveat']")
    assert page.locator("[data-role='sway-samples-caveat']").inner_text() == caveat
    assert errors == []


def client(served: Served) -> httpx.Client:
    """An HTTP client of the served API with its lab's key."""
    return httpx.Client(base_url=served.url, headers={"Authorization": f"Bearer {served.key}"}, timeout=60)


def stand(http: httpx.Client, demonstrator_id: str, name: str | None = "trial", seed: int = 0) -> str:
    """Upload a 20-s standing trial (named ``name``, none if None) to the demonstrator; its id."""
    body = {"protocol": "standing", "units": "cm", "samples": standing_trial(seed, 0.3)}
    if name is not None:
        body["name"] = name
    return str(ok(http.post(f"/v1/demonstrators/{demonstrator_id}/recordings", json=body))["id"])


def moving_and_standing(http: httpx.Client, name: str) -> str:
    """A demonstrator with recorded movements and a standing trial; its id."""
    dem_id = str(ok(http.post("/v1/demonstrators", json={"name": name}))["id"])
    record(http, dem_id, name, {"forward": 0.1})
    stand(http, dem_id, f"{name}, standing")
    return dem_id


def open_both_panels(page: Page, dem_id: str) -> None:
    """Open the demonstrator's motion readout and its quiet-standing panel; wait until both are drawn."""
    page.click(f"[data-demonstrator='{dem_id}'] [data-action='motion']")
    page.wait_for_selector(f"#motion[data-demonstrator='{dem_id}'] #kinematics tbody tr")
    page.click(f"[data-demonstrator='{dem_id}'] [data-action='sway']")
    page.wait_for_selector(f"#sway[data-demonstrator='{dem_id}'] tr[data-measure='area95']")


def test_a_key_of_another_lab_clears_every_panel_of_the_previous_lab(
    served: Served, browser: Browser
) -> None:
    http = client(served)
    dem_id = moving_and_standing(http, "first lab's subject")
    other_key = another_labs_key(served, "second lab")
    page, errors = open_dashboard(browser, served.url, served.key)
    console: list[str] = []
    page.on("console", lambda message: console.append(message.text) if message.type == "error" else None)
    open_both_panels(page, dem_id)

    page.fill("#key-input", other_key)
    page.click("#key-use")
    page.wait_for_selector("#demonstrators :text('No demonstrators yet.')")
    page.wait_for_selector("#mdps :text('No MDPs yet.')")
    for panel in ("#sway", "#motion", "#results", "#run"):
        assert page.locator(panel).is_hidden(), panel
    # Nothing of the first lab is left in the page, shown or hidden (titles, pickers, labels).
    text = page.evaluate("() => document.body.textContent")
    assert "first lab's subject" not in text and dem_id not in text
    assert page.locator("#sway-picture img, #comparison img").count() == 0
    assert errors == [] and console == []  # no 404 either (the page names its icon)


def test_deleting_a_demonstrator_or_refreshing_after_its_deletion_closes_its_panels(
    served: Served, browser: Browser
) -> None:
    http = client(served)
    on_page = moving_and_standing(http, "withdrawn on the page")
    elsewhere = moving_and_standing(http, "withdrawn elsewhere")
    page, errors = open_dashboard(browser, served.url, served.key)
    page.on("dialog", lambda dialog: dialog.accept())  # the confirm before the delete
    open_both_panels(page, on_page)
    page.click(f"[data-demonstrator='{on_page}'] [data-action='delete-demonstrator']")
    page.wait_for_selector(f".dem[data-demonstrator='{on_page}']", state="detached")
    page.wait_for_selector("#sway", state="hidden")
    page.wait_for_selector("#motion", state="hidden")

    open_both_panels(page, elsewhere)
    assert http.delete(f"/v1/demonstrators/{elsewhere}").status_code == 204
    page.click("#refresh")
    page.wait_for_selector(f".dem[data-demonstrator='{elsewhere}']", state="detached")
    page.wait_for_selector("#sway", state="hidden")
    page.wait_for_selector("#motion", state="hidden")
    message = page.locator("#message")
    assert message.inner_text() == f"Deleted elsewhere: demonstrator {elsewhere}; its panels are closed."
    assert "info" in (message.get_attribute("class") or "")
    assert errors == []


def test_a_trial_without_a_name_is_shown_by_its_id_and_no_panel_prints_null(
    served: Served, browser: Browser
) -> None:
    http = client(served)
    dem_id = str(ok(http.post("/v1/demonstrators", json={"name": "unnamed trials"}))["id"])
    rec_id = stand(http, dem_id, name=None)
    rec = ok(http.get(f"/v1/demonstrators/{dem_id}/recordings"), 200)["data"][0]
    shown = rec["name"] or rec_id
    page, errors = open_dashboard(browser, served.url, served.key)
    box = page.locator(f"[data-demonstrator='{dem_id}']")
    box.wait_for()
    assert "null" not in box.inner_text() and f"{shown} (standing" in box.inner_text()
    page.click(f"[data-demonstrator='{dem_id}'] [data-action='sway']")
    page.wait_for_selector(f"#sway[data-demonstrator='{dem_id}'] tr[data-measure='area95']")
    assert page.locator("#sway-recording option").all_inner_texts() == [shown]
    assert page.locator("#sway .sub").inner_text() == "1000 samples at 50 Hz over 20.000 s"
    assert "null" not in page.locator("#sway").inner_text()
    assert errors == []


def test_a_trials_picture_waits_behind_a_placeholder_while_the_trial_loads(
    served: Served, browser: Browser
) -> None:
    http = client(served)
    dem_id = str(ok(http.post("/v1/demonstrators", json={"name": "slow trial"}))["id"])
    stand(http, dem_id)
    page, errors = open_dashboard(browser, served.url, served.key)
    held: list[Route] = []
    page.route(
        lambda url: url.split("?")[0].endswith("/sway") and "format=png" not in url,
        lambda route: held.append(route),
    )
    page.click(f"[data-demonstrator='{dem_id}'] [data-action='sway']")
    while not held:
        page.wait_for_timeout(50)
    assert page.locator("#sway-picture img").count() == 0  # no picture without a source: no broken image
    assert page.locator("#sway-picture").inner_text() == "Loading…"
    for route in held:
        route.continue_()
    page.wait_for_function(
        "() => { const img = document.querySelector('#sway-picture img');"
        " return img && img.complete && img.naturalWidth > 0 && !img.hidden; }"
    )
    assert errors == []


def test_trials_in_metres_show_their_sway_in_millimetres_with_units_and_a_labelled_comparison(
    served: Served, browser: Browser
) -> None:
    http = client(served)
    dem_id = str(ok(http.post("/v1/demonstrators", json={"name": "sub-millimetre sway"}))["id"])
    # A warm-up without a label first (left out of the comparison), then two trials per vision, in metres:
    # the COP wanders by under a millimetre.
    trials = [
        ("warm-up", None),
        ("open 1", "open"),
        ("open 2", "open"),
        ("closed 1", "closed"),
        ("closed 2", "closed"),
    ]
    ids = []
    for k, (name, vision) in enumerate(trials):
        body = {
            "protocol": "standing",
            "name": name,
            "units": "m",
            "metadata": {"vision": vision} if vision else {},
            "samples": standing_trial(k, 0.0004 if vision != "closed" else 0.0006),
        }
        ids.append(ok(http.post(f"/v1/demonstrators/{dem_id}/recordings", json=body))["id"])
    sway = ok(http.get(f"/v1/recordings/{ids[-1]}/sway"), 200)  # the newest: the panel opens on it
    summary = ok(http.get(f"/v1/demonstrators/{dem_id}/sway-summary?by=vision"), 200)
    assert sway["units"] == summary["unit"] == "m" and summary["unlabelled"] == [ids[0]]
    assert sway["descriptors"]["rms_x"] < 1e-3  # sub-millimetre: 0.000 m to three decimals

    page, errors = open_dashboard(browser, served.url, served.key)
    page.click(f"[data-demonstrator='{dem_id}'] [data-action='sway']")
    page.wait_for_selector(f"#sway[data-demonstrator='{dem_id}'] .sway-measures tr[data-measure='area95']")
    measures = page.locator(".sway-measures")
    assert measures.locator("caption").inner_text().startswith("closed 2")
    assert measures.locator("thead th").all_inner_texts() == ["measure", "value", "unit"]
    shown = {
        key: measures.locator(f"tr[data-measure='{key}'] td").all_inner_texts()
        for key in ("area95", "rms_x", "mean_velocity", "mean_frequency")
    }
    d = sway["descriptors"]
    assert shown["area95"] == [f"{d['area95'] * 1e6:.3f}", "mm²"]
    assert shown["rms_x"] == [f"{d['rms_x'] * 1e3:.3f}", "mm"] and float(shown["rms_x"][0]) > 0
    assert shown["mean_velocity"] == [f"{d['mean_velocity'] * 1e3:.3f}", "mm/s"]
    assert shown["mean_frequency"] == [f"{d['mean_frequency']:.3f}", "Hz"]

    # The conditions compared: a caption, each measure's unit in its head, the Romberg quotient without one,
    # and the trial left out for want of the label named under the table.
    page.wait_for_selector(".sway-groups tr[data-group='romberg']")
    groups = page.locator(".sway-groups")
    assert "vision" in groups.locator("caption").inner_text()
    heads = {
        m: groups.locator(f"thead th[data-measure='{m}']").inner_text()
        for m in ("area95", "mean_velocity", "mean_frequency")
    }
    assert heads == {
        "area95": "95 % ellipse area\n(mm²)",
        "mean_velocity": "mean velocity\n(mm/s)",
        "mean_frequency": "mean frequency\n(Hz)",
    }
    closed = next(g for g in summary["groups"] if g["label"] == "closed")["measures"]["area95"]["value"]
    cell = groups.locator("tr[data-group='closed'] td").nth(0).inner_text().split("\n")[0]
    assert cell == f"{closed * 1e6:.3f}"
    romberg = groups.locator("tr[data-group='romberg'] td").nth(0).inner_text().split("\n")[0]
    assert romberg == f"{summary['romberg']['area95']['value']:.3f}"  # a ratio: no unit, not scaled
    assert "no unit" in groups.locator("tr[data-group='romberg'] th").inner_text()
    assert (
        page.locator("[data-role='sway-unlabelled']").inner_text()
        == "Left out, without a “vision” label: warm-up."
    )
    page.locator("#sway").scroll_into_view_if_needed()
    page.screenshot(path=ARTIFACTS / "9-sway-metres.png")
    assert errors == []


def test_a_demonstrators_buttons_go_from_reading_out_to_a_new_job_and_delete_comes_last(
    served: Served, browser: Browser
) -> None:
    http = client(served)
    dem_id = moving_and_standing(http, "button order")
    tasks = ok(http.get(f"/v1/demonstrators/{dem_id}/tasks"), 200)["data"]
    assert tasks  # the recorded movements' directions
    page, errors = open_dashboard(browser, served.url, served.key)
    box = page.locator(f".dem[data-demonstrator='{dem_id}']")
    box.locator(".dem-actions").wait_for()
    actions = box.locator(".dem-actions button").evaluate_all("bs => bs.map(b => b.dataset.action)")
    assert actions == ["motion", "sway", "new-job", "delete-demonstrator"]
    every = box.locator("button").evaluate_all("bs => bs.map(b => b.dataset.action)")
    assert every[:4] == actions  # under its name, before the task list that may scroll in its box

    box.locator("[data-action='new-job']").click()
    assert page.locator("#submit-demonstrator").input_value() == dem_id
    ticked = page.locator("#submit-tasks input[name='task']:checked").evaluate_all(
        "xs => xs.map(x => x.value)"
    )
    assert sorted(ticked) == sorted(t["id"] for t in tasks)
    assert page.evaluate("() => document.activeElement.id") == "submit-demonstrator"
    assert errors == []
