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
from tests.ui.helpers import ARTIFACTS, ok, open_dashboard

if TYPE_CHECKING:
    from playwright.sync_api import Browser

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
