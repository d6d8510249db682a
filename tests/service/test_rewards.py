"""A job's rewards (docs/api.md, "Rewards"): the listing with statistics and truth scores, and every download format.

Results are written straight to the database (`fitted_job`), so no worker is needed.
"""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from PIL import Image
from scipy.stats import pearsonr
from sqlalchemy import event

from metairl_engine.mdp import Layout
from service.api.async_db import ENGINE
from service.files.images import heatmap_pixel_size, heatmap_png
from service.results.downloads import download
from service.results.rewards import reward_context
from service.store.models.jobs import Reward
from tests.service.helpers import add_demonstrations, created, fitted_job, make_mdp, make_task, store_results

WIDTH, HEIGHT = 5, 4
N_STATES = WIDTH * HEIGHT
RIGHT = [{"states": [0, 1, 2, 3, 4], "actions": [0, 0, 0, 0]}, {"states": [10, 11, 12], "actions": [0, 0]}]
UP = [{"states": [2, 7, 12, 17], "actions": [1, 1, 1]}]


def grid(client: TestClient, auth: dict[str, str], **overrides: Any) -> dict[str, Any]:
    """A 5×4 grid MDP, 4 moves (state = y·5 + x; action 0 east, 1 north)."""
    body = {"kind": "grid", "name": "plate", "width": WIDTH, "height": HEIGHT, "moves": 4, "gamma": 0.9}
    return created(client.post("/v1/mdps", json=body | overrides, headers=auth))


def random_rewards(n_rewards: int, n_states: int, seed: int = 0) -> np.ndarray:
    """Distinct float32 rewards, baseline first."""
    return np.random.default_rng(seed).normal(size=(n_rewards, n_states)).astype(np.float32)


@pytest.fixture
def job(app: FastAPI, client: TestClient, auth: dict[str, str]) -> dict[str, Any]:
    """A succeeded job on the 5×4 grid: baseline, 'walk right' and 'walk up' rewards."""
    rewards = random_rewards(3, N_STATES)
    demonstrations = {"walk right": RIGHT, "walk up": UP}
    fitted = fitted_job(
        app, client, auth, mdp=grid(client, auth), demonstrations=demonstrations, rewards=rewards
    )
    return fitted | {"rewards": rewards}


def get(client: TestClient, auth: dict[str, str], reward_id: str, **params: Any) -> Any:
    """GET a reward download, asserting 200."""
    response = client.get(f"/v1/rewards/{reward_id}", params=params, headers=auth)
    assert response.status_code == 200, response.text
    return response


def test_listing_has_summaries_truth_scores_and_working_links(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    truth = np.arange(N_STATES, dtype=np.float32) % WIDTH  # highest (4) on the right column
    right_task = job["task_ids"][0]
    created(
        client.put(f"/v1/tasks/{right_task}/true-reward", json={"values": truth.tolist()}, headers=auth), 200
    )

    listing = created(client.get(f"/v1/jobs/{job['job_id']}/rewards", headers=auth), 200)
    assert [listing["baseline"]["reward_id"], *(t["reward_id"] for t in listing["tasks"])] == job[
        "reward_ids"
    ]
    assert [t["task_id"] for t in listing["tasks"]] == job["task_ids"]
    assert [t["task_name"] for t in listing["tasks"]] == ["walk right", "walk up"]
    assert listing["baseline"]["kind"] == "baseline" and listing["baseline"]["task_id"] is None

    for ref, values in zip([listing["baseline"], *listing["tasks"]], job["rewards"], strict=True):
        wide = values.astype(np.float64)
        assert ref["summary"] == pytest.approx(
            {"min": wide.min(), "max": wide.max(), "mean": wide.mean(), "std": wide.std()}
            | {"argmax_state": int(wide.argmax()), "argmin_state": int(wide.argmin())}
        )
        assert set(ref["links"]) == {"json", "npy", "csv", "png"} | (
            {"key_states"} if ref["task_id"] else set()
        )
        for link in ref["links"].values():
            assert client.get(link, headers=auth).status_code == 200, link

    right, up = listing["tasks"]
    assert right["truth_pearson"] == pytest.approx(pearsonr(job["rewards"][1], truth)[0], abs=1e-6)
    assert up["truth_pearson"] is None and listing["baseline"]["truth_pearson"] is None
    assert right["truth_pearson_excluding_top"] is None  # only when asked

    asked = client.get(
        f"/v1/jobs/{job['job_id']}/rewards", params={"exclude_top_truth": "true"}, headers=auth
    ).json()
    below = truth < truth.max()
    expected = pearsonr(job["rewards"][1][below], truth[below])[0]
    assert asked["tasks"][0]["truth_pearson_excluding_top"] == pytest.approx(expected, abs=1e-6)
    assert asked["tasks"][0]["truth_pearson_excluding_top"] != pytest.approx(right["truth_pearson"], abs=1e-3)
    assert asked["tasks"][1]["truth_pearson_excluding_top"] is None


def test_listing_before_success_is_409(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    job = created(
        client.post("/v1/jobs", json={"demonstrator_id": task["demonstrator_id"]}, headers=auth), 202
    )
    response = client.get(f"/v1/jobs/{job['id']}/rewards", headers=auth)
    assert response.status_code == 409 and "succeeded" in response.json()["detail"]


def test_json_npy_and_csv_round_trip_exactly(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    reward_id, values = job["reward_ids"][1], job["rewards"][1]

    as_json = get(client, auth, reward_id).json()
    assert (as_json["reward_id"], as_json["n_states"], as_json["quantity"]) == (reward_id, N_STATES, "reward")
    np.testing.assert_array_equal(np.asarray(as_json["values"], dtype=np.float32), values)

    npy = np.load(io.BytesIO(get(client, auth, reward_id, format="npy").content), allow_pickle=False)
    assert npy.dtype == np.float32 and npy.shape == (N_STATES,)
    np.testing.assert_array_equal(npy, values)

    rows = list(csv.DictReader(io.StringIO(get(client, auth, reward_id, format="csv").text)))
    assert list(rows[0]) == ["state", "x", "y", "channel", "reward"] and len(rows) == N_STATES
    np.testing.assert_array_equal(np.array([r["reward"] for r in rows], dtype=np.float32), values)
    state = np.array([int(r["state"]) for r in rows])
    assert [int(r["x"]) for r in rows] == (state % WIDTH).tolist()
    assert [int(r["y"]) for r in rows] == (state // WIDTH).tolist()


def test_value_and_policy_download_like_rewards(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    reward_id, values = job["reward_ids"][1], job["rewards"][1]
    value = np.load(io.BytesIO(get(client, auth, reward_id, format="npy", quantity="value").content))
    np.testing.assert_array_equal(value, 2 * values)

    policy = get(client, auth, reward_id, quantity="policy").json()
    assert (policy["quantity"], policy["n_actions"], np.shape(policy["values"])) == (
        "policy",
        4,
        (N_STATES, 4),
    )
    header = get(client, auth, reward_id, quantity="policy", format="csv").text.splitlines()[0]
    assert header == "state,x,y,channel,a0,a1,a2,a3"

    baseline = client.get(f"/v1/rewards/{job['reward_ids'][0]}", params={"quantity": "value"}, headers=auth)
    assert baseline.status_code == 409 and "baseline" in baseline.json()["detail"]


def test_png_is_the_rendered_heatmap_titled_task_and_demonstrator(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    layout = Layout(width=WIDTH, height=HEIGHT)
    response = get(client, auth, job["reward_ids"][1], format="png")
    assert response.headers["content-type"] == "image/png"
    image = Image.open(io.BytesIO(response.content))
    assert image.format == "PNG" and image.size == heatmap_pixel_size(layout=layout)
    assert response.content == heatmap_png(job["rewards"][1], layout=layout, title="walk right — patient 1")

    baseline = get(client, auth, job["reward_ids"][0], format="png", overlay="demos").content
    drawn = [np.array(t["states"]) for t in RIGHT + UP]
    assert baseline == heatmap_png(
        job["rewards"][0], layout=layout, title="baseline — patient 1", trajectories=drawn
    )
    value = get(client, auth, job["reward_ids"][1], format="png", quantity="value").content
    assert value == heatmap_png(
        2 * job["rewards"][1], layout=layout, title="walk right — patient 1 (value)", colorbar_label="value"
    )


def test_velocity_grid_png_has_a_panel_per_direction(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = grid(client, auth, width=3, height=3, moves=8, velocity=True)
    diagonal = [{"states": [0, 1 * 9 + 4, 1 * 9 + 8], "actions": [1, 1]}]  # (0,0) → (1,1) → (2,2) moving NE
    fitted = fitted_job(
        app, client, auth, mdp=mdp, demonstrations={"diagonal": diagonal}, rewards=random_rewards(2, 72)
    )
    png = get(client, auth, fitted["reward_ids"][1], format="png").content
    eight = heatmap_pixel_size(layout=Layout(width=3, height=3, channels=8))
    assert Image.open(io.BytesIO(png)).size == eight != heatmap_pixel_size(layout=Layout(width=3, height=3))
    assert eight == (4 * 300 + 100, 2 * 325 + 75)  # 2 rows × 4 panels and the colour bar, at 100 dpi


def test_the_baseline_says_how_to_read_it_where_that_needs_saying(
    app: FastAPI, client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    def baseline(job_id: str) -> dict[str, Any]:
        response = client.get(f"/v1/jobs/{job_id}/rewards", headers=auth)
        assert response.status_code == 200, response.text
        listing = response.json()
        assert all(task["note"] is None for task in listing["tasks"])
        return listing["baseline"]

    assert baseline(job["job_id"])["note"] is None
    # No baseline without sharing, nor from maxent whatever the sharing; shared_maxent always learns one.
    for config, averaged in (
        ({"sharing": "none"}, True),
        ({"method": "maxent"}, True),
        ({"method": "shared_maxent", "sharing": "none"}, False),
    ):
        fitted = fitted_job(
            app,
            client,
            auth,
            mdp=grid(client, auth),
            demonstrations={"walk right": RIGHT},
            rewards=random_rewards(2, N_STATES),
            demonstrator=f"fitted with {config}",
            config=config,
        )
        note = baseline(fitted["job_id"])["note"]
        assert ("mean of the task rewards" in note) if averaged else note is None
    velocity = grid(client, auth, width=3, height=3, moves=8, velocity=True)
    moving = fitted_job(
        app,
        client,
        auth,
        mdp=velocity,
        demonstrations={"diagonal": [{"states": [0, 1 * 9 + 4, 1 * 9 + 8], "actions": [1, 1]}]},
        rewards=random_rewards(2, 72),
        demonstrator="on a plate",
    )
    assert "Out-and-back movements" in baseline(moving["job_id"])["note"]


def test_etag_gives_304_and_differs_per_variant(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    reward_id = job["reward_ids"][1]
    first = get(client, auth, reward_id, format="csv")
    etag = first.headers["ETag"]
    assert etag.startswith('"') and first.headers["Content-Disposition"] == (
        'attachment; filename="patient-1_walk-right_reward.csv"'
    )
    for header in (etag, f"W/{etag}", f'"other", {etag}', "*"):
        again = client.get(
            f"/v1/rewards/{reward_id}", params={"format": "csv"}, headers=auth | {"If-None-Match": header}
        )
        assert (again.status_code, again.content, again.headers["ETag"]) == (304, b"", etag), header
    stale = client.get(
        f"/v1/rewards/{reward_id}", params={"format": "csv"}, headers=auth | {"If-None-Match": '"x"'}
    )
    assert stale.status_code == 200 and stale.content == first.content

    tags = {
        get(client, auth, rid, **params).headers["ETag"]
        for rid in job["reward_ids"][1:]
        for params in (
            {},
            {"format": "npy"},
            {"format": "png"},
            {"format": "png", "overlay": "demos"},
            {"quantity": "value"},
        )
    }
    assert len(tags) == 10
    assert get(client, auth, reward_id, format="png").headers["Content-Disposition"] == (
        'inline; filename="patient-1_walk-right_reward.png"'
    )
    baseline = get(client, auth, job["reward_ids"][0], format="npy").headers["Content-Disposition"]
    assert baseline == 'attachment; filename="patient-1_baseline_reward.npy"'


def test_png_without_layout_or_of_a_policy_is_409(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = make_mdp(client, auth, layout=None)
    fitted = fitted_job(
        app,
        client,
        auth,
        mdp=mdp,
        demonstrations={"reach": [{"states": [0, 1, 2], "actions": [1, 1]}]},
        rewards=random_rewards(2, 3),
    )
    listing = client.get(f"/v1/jobs/{fitted['job_id']}/rewards", headers=auth).json()
    assert "png" not in listing["tasks"][0]["links"]
    response = client.get(f"/v1/rewards/{fitted['reward_ids'][1]}", params={"format": "png"}, headers=auth)
    assert response.status_code == 409 and "no layout" in response.json()["detail"]
    assert get(client, auth, fitted["reward_ids"][1], format="csv").text.splitlines()[0] == "state,reward"


def test_bad_parameters_are_422_naming_them(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    reward_id = job["reward_ids"][1]
    cases = [
        ({"format": "xlsx"}, 422, "format"),
        ({"quantity": "advantage"}, 422, "quantity"),
        ({"format": "csv", "overlay": "demos"}, 422, "overlay"),
    ]
    for params, status, parameter in cases:
        response = client.get(f"/v1/rewards/{reward_id}", params=params, headers=auth)
        assert response.status_code == status, params
        assert response.headers["content-type"] == "application/problem+json"
        assert response.json()["errors"][0]["parameter"] == parameter
    policy_png = client.get(
        f"/v1/rewards/{reward_id}", params={"format": "png", "quantity": "policy"}, headers=auth
    )
    assert policy_png.status_code == 409 and "policy" in policy_png.json()["detail"]
    assert client.get("/v1/rewards/rwd_nope", headers=auth).status_code == 404


def test_npy_and_json_come_from_one_statement_with_the_key_check_and_the_same_answers_as_the_general_path(
    app: FastAPI, client: TestClient, auth: dict[str, str], auth_b: dict[str, str], job: dict[str, Any]
) -> None:
    """npy and json are served from the stored bytes in one statement on the async engine, the API-key check
    included (recording the key's use, at most once a minute, aside) and nothing on the sync engine; the bytes,
    ETag and file name equal those of `service.results.downloads.download`, which builds them from the loaded array."""
    statements: list[str] = []
    sync_statements: list[str] = []

    def note(*args: Any) -> None:
        if not args[2].startswith("UPDATE api_keys"):
            statements.append(args[2])

    event.listen(client.app_state[ENGINE].sync_engine, "before_cursor_execute", note)
    event.listen(app.state.engine, "before_cursor_execute", lambda *args: sync_statements.append(args[2]))
    with app.state.sessionmaker() as session:
        lab_id = session.get_one(Reward, job["reward_ids"][0]).lab_id
    for reward_id in job["reward_ids"]:
        for fmt in ("npy", "json"):
            for quantity in ("reward", "value", "policy"):
                statements.clear()
                sync_statements.clear()
                response = get_raw(client, auth, reward_id, format=fmt, quantity=quantity)
                if reward_id == job["reward_ids"][0] and quantity != "reward":
                    assert response.status_code == 409 and "baseline" in response.json()["detail"]
                    continue
                assert response.status_code == 200 and len(statements) == 1, statements
                assert "api_keys" in statements[0] and not sync_statements, sync_statements
                with app.state.sessionmaker() as session:
                    ctx = reward_context(session, reward_id, lab_id=lab_id)
                    general = download(
                        session, ctx, fmt=fmt, quantity=quantity, overlay="none", if_none_match=None
                    )
                assert response.content == general.content
                assert response.headers["ETag"] == general.etag
                assert general.filename in response.headers["Content-Disposition"]
                statements.clear()
                again = get_raw(
                    client,
                    auth,
                    reward_id,
                    format=fmt,
                    quantity=quantity,
                    headers={"If-None-Match": str(general.etag)},
                )
                assert (again.status_code, again.content, len(statements)) == (304, b"", 1)
                stale = get_raw(
                    client, auth, reward_id, format=fmt, quantity=quantity, headers={"If-None-Match": '"x"'}
                )
                assert stale.status_code == 200 and stale.content == response.content
    other_lab = get_raw(client, auth_b, job["reward_ids"][1], format="npy")
    missing = get_raw(client, auth, "rwd_nope", format="npy")
    assert other_lab.status_code == missing.status_code == 404


def get_raw(
    client: TestClient,
    auth: dict[str, str],
    reward_id: str,
    headers: dict[str, str] | None = None,
    **params: Any,
) -> Any:
    """The response of a download, whatever its status."""
    return client.get(f"/v1/rewards/{reward_id}", params=params, headers=auth | (headers or {}))


def test_uncertainty_and_evidence_download_like_the_reward_in_every_format(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    mdp = grid(client, auth)
    dem = created(client.post("/v1/demonstrators", json={"name": "spread"}, headers=auth))
    task = make_task(client, auth, demonstrator_id=dem["id"], mdp_id=mdp["id"])
    add_demonstrations(client, auth, task["id"], RIGHT)
    job = created(client.post("/v1/jobs", json={"demonstrator_id": dem["id"]}, headers=auth), 202)
    rewards = random_rewards(2, N_STATES)
    spread = np.abs(random_rewards(2, N_STATES, seed=1))
    seen = np.zeros((2, N_STATES), dtype=np.float32)
    seen[:, [0, 1, 2, 3, 4, 10, 11, 12]] = 1.0
    ids = store_results(
        app,
        job_id=job["id"],
        baseline=rewards[0],
        task_rewards=[rewards[1]],
        n_actions=4,
        uncertainty=list(spread),
        evidence=list(seen),
    )
    for reward_id, mine, evidence in zip(ids, spread, seen, strict=True):
        for quantity, expected in (("uncertainty", mine), ("evidence", evidence)):
            body = get(client, auth, reward_id, quantity=quantity).json()
            assert body["quantity"] == quantity and body["n_states"] == N_STATES
            np.testing.assert_array_equal(np.asarray(body["values"], dtype=np.float32), expected)
            npy = np.load(io.BytesIO(get(client, auth, reward_id, quantity=quantity, format="npy").content))
            np.testing.assert_array_equal(npy, expected)
            table = list(
                csv.DictReader(
                    io.StringIO(get(client, auth, reward_id, quantity=quantity, format="csv").text)
                )
            )
            assert len(table) == N_STATES and quantity in table[0]
            png = get(client, auth, reward_id, quantity=quantity, format="png")
            assert png.headers["content-type"] == "image/png"
    listing = created(client.get(f"/v1/jobs/{job['id']}/rewards", headers=auth), 200)
    assert (
        listing["baseline"]["links"]["uncertainty_png"]
        == f"/v1/rewards/{ids[0]}?quantity=uncertainty&format=png"
    )


def test_a_reward_without_a_spread_says_why_with_a_409(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    for quantity, reason in (
        ("uncertainty", "single ensemble member"),
        ("evidence", "before evidence was kept"),
    ):
        for fmt in ("json", "npy", "png"):
            response = get_raw(client, auth, job["reward_ids"][1], quantity=quantity, format=fmt)
            assert response.status_code == 409 and reason in response.json()["detail"], (quantity, fmt)
    listing = client.get(f"/v1/jobs/{job['job_id']}/rewards", headers=auth).json()
    assert "uncertainty" not in listing["tasks"][0]["links"]
