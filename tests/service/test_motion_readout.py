"""The motion readout over HTTP (docs/api.md, "Motion readout"): a demonstrator's kinematic summary per direction, two
demonstrators' comparison (JSON with the learned-reward readout, and a PNG), the demonstrations a recording
was cut into (JSON and CSV), 404 for another lab's resources and 409 without recordings."""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_engine.grids import DIRECTION_NAMES, velocity_coords
from metairl_engine.motion.recording import Recording
from metairl_engine.sim.controller_patient import ControllerSettings, simulate_controller_patient
from service.results import readout
from tests.service.helpers import (
    PLATE,
    UNIT,
    cop_rows,
    created,
    make_demonstrator,
    make_recording,
    store_results,
)

WEAK = {"forward": 0.12, "right": 0.12, "left": 0.06}
"""Hand-made reach per direction (metres): the left side is weak."""


def by_direction(body: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """A readout's `directions` keyed by direction name."""
    return {row["direction"]: row for row in body["directions"]}


def rows_of(rec: Recording) -> list[dict[str, Any]]:
    """A simulated session as JSON sample rows."""
    assert rec.instruction is not None
    return [
        {"t": float(t), "x": float(x), "y": float(y), "instruction": str(i)}
        for t, x, y, i in zip(rec.t, rec.x, rec.y, rec.instruction, strict=True)
    ]


@pytest.fixture(scope="module")
def controller_sessions() -> dict[str, list[dict[str, Any]]]:
    """A tiny controller patient, weak on the left: both sessions as sample rows."""
    patient = simulate_controller_patient(
        ControllerSettings(width=20, height=20, directions=("forward", "right", "left"), repetitions=3)
    )
    return {name: rows_of(rec) for name, rec in patient.sessions.items()}


def upload(client: TestClient, auth: dict[str, str], dem_id: str, samples: list[dict[str, Any]]) -> Any:
    """Upload sample rows onto a 20×20 velocity grid; the recording."""
    body = {"bounds": PLATE, "grid": {"width": 20, "height": 20}, "samples": samples}
    return created(client.post(f"/v1/demonstrators/{dem_id}/recordings", json=body, headers=auth))


def test_summary_has_the_contract_fields_and_shows_the_weak_side(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    make_recording(client, auth, dem["id"], WEAK)
    response = client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth)
    body = created(response, 200)
    assert body["demonstrator_id"] == dem["id"] and body["n_recordings"] == 1
    assert body["learned"] is None  # no succeeded job yet
    assert set(body["units"]) == {"peak_reach", "path_length", "deviation", "time_to_peak_s", "mean_speed"}
    assert [row["direction"] for row in body["directions"]] == ["right", "forward", "left"]  # canonical order
    rows = by_direction(body)
    for name, reach in WEAK.items():
        row = rows[name]
        assert row["n_segments"] == 3
        for descriptor in ("peak_reach", "path_length", "deviation", "time_to_peak_s", "mean_speed"):
            d = row[descriptor]
            assert d["low"] <= d["mean"] <= d["high"], (name, descriptor, d)
        assert row["peak_reach"]["mean"] == pytest.approx(reach, rel=0.15)
        assert row["path_length"]["mean"] == pytest.approx(2 * reach, rel=0.25)
        assert row["deviation"]["mean"] < 0.1 * reach
    assert rows["left"]["peak_reach"]["high"] < min(
        rows[n]["peak_reach"]["low"] for n in ("forward", "right")
    )
    again = client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth).json()
    assert again == body  # seeded bootstrap


def test_summary_pools_recordings_and_reads_a_controller_patients_weak_side(
    client: TestClient, auth: dict[str, str], controller_sessions: dict[str, list[dict[str, Any]]]
) -> None:
    dem = make_demonstrator(client, auth)
    upload(client, auth, dem["id"], controller_sessions["unstimulated"])
    one = by_direction(client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth).json())
    assert one["left"]["peak_reach"]["mean"] < min(one[n]["peak_reach"]["mean"] for n in ("forward", "right"))
    upload(client, auth, dem["id"], controller_sessions["unstimulated"])
    body = client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth).json()
    assert body["n_recordings"] == 2
    two = by_direction(body)
    for name in ("forward", "right", "left"):
        assert two[name]["n_segments"] == 2 * one[name]["n_segments"]
        assert two[name]["peak_reach"]["mean"] == pytest.approx(one[name]["peak_reach"]["mean"], rel=1e-5)


def test_comparison_gives_b_minus_a_with_intervals_and_a_png(
    client: TestClient, auth: dict[str, str], controller_sessions: dict[str, list[dict[str, Any]]]
) -> None:
    a = make_demonstrator(client, auth, name="P1 unstimulated")
    b = make_demonstrator(client, auth, name="P1 stimulated")
    upload(client, auth, a["id"], controller_sessions["unstimulated"])
    upload(client, auth, b["id"], controller_sessions["stimulated"])
    body = created(
        client.post("/v1/motion-comparisons", json={"a": a["id"], "b": b["id"]}, headers=auth), 200
    )
    assert body["a"]["demonstrator_id"] == a["id"] and body["b"]["demonstrator_id"] == b["id"]
    assert body["learned"] == {"a": None, "b": None}
    assert body["links"]["png"] == "/v1/motion-comparisons?format=png"
    summary_a, summary_b = by_direction(body["a"]), by_direction(body["b"])
    rows = by_direction(body)
    assert set(rows) == {"forward", "right", "left"}
    for name, row in rows.items():
        diff = row["peak_reach_diff"]
        expected = summary_b[name]["peak_reach"]["mean"] - summary_a[name]["peak_reach"]["mean"]
        assert diff["mean"] == pytest.approx(expected)
        assert diff["mean"] > 0 and diff["low"] <= diff["mean"] <= diff["high"], (name, diff)
        assert (row["n_a"], row["n_b"]) == (summary_a[name]["n_segments"], summary_b[name]["n_segments"])
    reverse = client.post("/v1/motion-comparisons", json={"a": b["id"], "b": a["id"]}, headers=auth).json()
    assert by_direction(reverse)["left"]["peak_reach_diff"]["mean"] == pytest.approx(
        -rows["left"]["peak_reach_diff"]["mean"]
    )
    png = client.post("/v1/motion-comparisons?format=png", json={"a": a["id"], "b": b["id"]}, headers=auth)
    assert png.status_code == 200 and png.headers["content-type"] == "image/png"
    assert png.content.startswith(b"\x89PNG\r\n\x1a\n")


def test_comparison_and_summary_carry_each_sides_latest_learned_readout(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    a = make_demonstrator(client, auth)
    b = make_demonstrator(client, auth)
    make_recording(client, auth, a["id"], WEAK)
    recording = make_recording(client, auth, b["id"], WEAK)
    task_ids = [t["task_id"] for t in recording["tasks"]]
    job = created(client.post("/v1/jobs", json={"demonstrator_id": b["id"]}, headers=auth), 202)
    n_states = 8 * 10 * 10
    rng = np.random.default_rng(0)
    baseline = rng.standard_normal(n_states).astype(np.float32)
    ids = store_results(
        app,
        job_id=job["id"],
        baseline=baseline,
        task_rewards=[baseline + 0.1 * rng.standard_normal(n_states).astype(np.float32) for _ in task_ids],
        n_actions=8,
    )
    body = created(
        client.post("/v1/motion-comparisons", json={"a": a["id"], "b": b["id"]}, headers=auth), 200
    )
    assert body["learned"]["a"] is None
    learned = body["learned"]["b"]
    assert learned["job_id"] == job["id"] and learned["baseline_reward_id"] == ids[0]
    assert "distance from the centre" in learned["caveat"]
    directions = by_direction(learned)
    labels = {t["task_id"]: t["label"] for t in recording["tasks"]}
    assert set(directions) == set(WEAK)
    for reward_id, task_id in zip(ids[1:], job["task_ids"], strict=True):
        row = directions[labels[task_id]]
        assert row["task_id"] == task_id and row["reward_id"] == reward_id
        assert row["n_visited_states"] > 0 and row["task_baseline_pearson"] > 0.9
        assert row["baseline_ring_centred"] is not None
        assert row["path_bend"] is None  # three directions: no loop around the centre to integrate
    summary = created(client.get(f"/v1/demonstrators/{b['id']}/motion-summary", headers=auth), 200)
    assert summary["learned"] == learned  # the summary carries the same readout of b's latest job
    # three directions cannot be ranked with confidence: the verdict says so instead of endorsing the readout
    assert (
        learned["agreement"]["verdict"] == "undetermined" and "at least 4" in learned["agreement"]["detail"]
    )
    assert learned["recordings_after_job"] == []
    later = make_recording(client, auth, b["id"], WEAK)  # the fit never saw it: the readout says so
    again = created(client.get(f"/v1/demonstrators/{b['id']}/motion-summary", headers=auth), 200)
    assert again["learned"]["recordings_after_job"] == [later["id"]]


FAN = {"right": 0.14, "forward right": 0.12, "forward": 0.10, "forward left": 0.08, "left": 0.06}
"""Hand-made reach falling from right to left: five directions, clearly ordered."""


def toward(favoured: str, *, size: int = 10) -> np.ndarray:
    """A velocity-grid baseline that grows with the cosine between a cell's bearing from the centre and
    ``favoured``: its readout ranks the directions by their angle from it."""
    states = np.arange(8 * size * size)
    x, y, _ = velocity_coords(states, width=size, height=size)
    bearing = np.arctan2(y - (size - 1) / 2, x - (size - 1) / 2)
    return np.cos(bearing - DIRECTION_NAMES.index(favoured) * np.pi / 4).astype(np.float32)


@pytest.mark.parametrize(("favoured", "verdict"), [("right", "agrees"), ("left", "disagrees")])
def test_the_verdict_says_whether_the_learned_readout_ranks_directions_as_the_reach_does(
    app: FastAPI, client: TestClient, auth: dict[str, str], favoured: str, verdict: str
) -> None:
    dem = make_demonstrator(client, auth)
    make_recording(client, auth, dem["id"], FAN)
    job = created(client.post("/v1/jobs", json={"demonstrator_id": dem["id"]}, headers=auth), 202)
    baseline = toward(favoured)
    store_results(
        app, job_id=job["id"], baseline=baseline, task_rewards=[baseline] * len(job["task_ids"]), n_actions=8
    )
    learned = created(client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth), 200)[
        "learned"
    ]
    agreement = learned["agreement"]
    assert agreement["verdict"] == verdict, agreement
    assert isinstance(agreement["detail"], str) and agreement["detail"].endswith(".")
    assert (agreement["spearman"] > 0) == (verdict == "agrees")
    assert (
        agreement["bend_spearman"] is None and agreement["bend_p_value"] is None
    )  # five directions: no bend
    other = make_demonstrator(client, auth)
    make_recording(client, auth, other["id"], FAN)
    body = client.post("/v1/motion-comparisons", json={"a": other["id"], "b": dem["id"]}, headers=auth).json()
    assert body["learned"]["b"]["agreement"] == agreement


def learned_with_paths_bent_forward(
    app: FastAPI, client: TestClient, auth: dict[str, str], favoured: str
) -> dict[str, Any]:
    """The learned readout of a demonstrator whose paths in all eight directions reach alike and bend toward
    forward (counter-clockwise on the right half, clockwise on the left), with a job's baseline `toward`
    ``favoured``."""
    dem = make_demonstrator(client, auth)
    bend = {d: 0.06 * unit[0] for d, unit in UNIT.items()}
    make_recording(client, auth, dem["id"], dict.fromkeys(DIRECTION_NAMES, 0.12), bend=bend)
    job = created(client.post("/v1/jobs", json={"demonstrator_id": dem["id"]}, headers=auth), 202)
    baseline = toward(favoured)
    store_results(
        app, job_id=job["id"], baseline=baseline, task_rewards=[baseline] * len(job["task_ids"]), n_actions=8
    )
    learned: dict[str, Any] = created(
        client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth), 200
    )["learned"]
    return learned


def test_path_bend_ranks_the_side_every_path_bends_toward_highest(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    learned = learned_with_paths_bent_forward(app, client, auth, "right")
    bends = {d: row["path_bend"] for d, row in by_direction(learned).items()}
    assert set(bends) == set(DIRECTION_NAMES)
    assert max(bends, key=bends.__getitem__) == "forward" and min(bends, key=bends.__getitem__) == "backward"


def test_a_learned_readout_favouring_the_side_the_paths_bend_away_from_disagrees(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    agreement = learned_with_paths_bent_forward(app, client, auth, "backward")["agreement"]
    assert agreement["verdict"] == "disagrees", agreement
    assert agreement["bend_spearman"] < -0.9 and agreement["bend_p_value"] <= 0.05
    assert "against the path bend" in agreement["detail"]


def test_another_labs_demonstrators_are_not_found(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    mine = make_demonstrator(client, auth)
    make_recording(client, auth, mine["id"])
    theirs = make_demonstrator(client, auth_b)
    make_recording(client, auth_b, theirs["id"])
    response = client.get(f"/v1/demonstrators/{mine['id']}/motion-summary", headers=auth_b)
    assert response.status_code == 404
    assert response.headers["content-type"].startswith("application/problem+json")
    for body in ({"a": mine["id"], "b": theirs["id"]}, {"a": theirs["id"], "b": mine["id"]}):
        response = client.post("/v1/motion-comparisons", json=body, headers=auth_b)
        assert response.status_code == 404, body
        assert mine["id"] in response.json()["detail"]


def test_a_demonstrator_compared_with_itself_is_422_at_b_with_the_bodys_other_problems(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    for extra, expected in (({}, ["/b"]), ({"bootstrap": 100}, ["/bootstrap", "/b"])):
        response = client.post(
            "/v1/motion-comparisons", json={"a": dem["id"], "b": dem["id"]} | extra, headers=auth
        )
        assert response.status_code == 422, response.text
        assert [e["pointer"] for e in response.json()["errors"]] == expected
    assert "same demonstrator" in response.json()["errors"][1]["message"]


def test_no_recordings_is_a_409_with_a_reason(client: TestClient, auth: dict[str, str]) -> None:
    empty = make_demonstrator(client, auth)
    recorded = make_demonstrator(client, auth)
    make_recording(client, auth, recorded["id"])
    response = client.get(f"/v1/demonstrators/{empty['id']}/motion-summary", headers=auth)
    assert response.status_code == 409
    assert response.headers["content-type"].startswith("application/problem+json")
    assert "no recordings" in response.json()["detail"] and empty["id"] in response.json()["detail"]
    for body in ({"a": empty["id"], "b": recorded["id"]}, {"a": recorded["id"], "b": empty["id"]}):
        response = client.post("/v1/motion-comparisons", json=body, headers=auth)
        assert response.status_code == 409 and empty["id"] in response.json()["detail"]


def test_a_recordings_demonstrations_download_as_json_and_csv(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    recording = make_recording(client, auth, dem["id"], {"forward": 0.12, "forward left": 0.1}, repetitions=2)
    path = f"/v1/recordings/{recording['id']}/demonstrations"
    body = created(client.get(path, headers=auth), 200)
    assert body["recording_id"] == recording["id"] and body["mdp_id"] == recording["mdp_id"]
    names = [t["trajectory"] for t in body["trajectories"]]
    assert names == ["forward/0", "forward/1", "forward left/0", "forward left/1"]
    tasks = {t["label"]: t for t in recording["tasks"]}
    for label, task in tasks.items():
        mine = [t for t in body["trajectories"] if t["label"] == label]
        assert {t["task_id"] for t in mine} == {task["task_id"]}
        assert {t["demonstration_id"] for t in mine} == {task["demonstration_id"]}
        assert sum(len(t["actions"]) for t in mine) == task["n_steps"]
        for t in mine:
            assert len(t["states"]) in (len(t["actions"]), len(t["actions"]) + 1)
    forward = client.get(path, params={"label": "forward"}, headers=auth).json()["trajectories"]
    assert [t["trajectory"] for t in forward] == ["forward/0", "forward/1"]

    response = client.get(path, params={"format": "csv", "label": "forward"}, headers=auth)
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    table = list(csv.DictReader(io.StringIO(response.text)))
    assert list(table[0]) == ["trajectory", "step", "state", "action"]
    assert [int(r["state"]) for r in table if r["trajectory"] == "forward/0"] == forward[0]["states"]
    # the CSV is what a demonstrations upload takes: it goes back into the task as it came out
    again = client.post(
        f"/v1/tasks/{tasks['forward']['task_id']}/demonstrations",
        files={"file": ("forward.csv", response.content)},
        headers=auth,
    )
    assert created(again)["n_steps"] == tasks["forward"]["n_steps"]

    assert client.get(path, headers=auth_b).status_code == 404


def test_hand_made_rows_cover_every_direction_once_per_repetition() -> None:
    rows = cop_rows({"forward": 0.1, "backward right": 0.05}, repetitions=2)
    instructed = [r["instruction"] for r in rows]
    assert instructed.count("forward") == instructed.count("backward right") == 2 * 60
    assert all(PLATE["x_min"] <= r["x"] <= PLATE["x_max"] for r in rows)


def test_the_verdict_resamples_each_movement_of_a_recording_not_its_upload_batch(
    app: FastAPI, client: TestClient, auth: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A recording stores each direction's movements as one batch of trajectories: the bend's interval
    resamples the movements (3 per direction here), never the one batch."""
    seen: dict[str, int] = {}
    real = readout.path_offsets

    def counting(paths: Any, **grid: int) -> dict[str, list[float]]:
        seen.update({d: len(p) for d, p in paths.items()})
        return real(paths, **grid)

    monkeypatch.setattr(readout, "path_offsets", counting)
    learned_with_paths_bent_forward(app, client, auth, "backward")
    assert seen == dict.fromkeys(DIRECTION_NAMES, 3)


def test_sessions_in_metres_and_centimetres_compare_in_one_unit_and_an_unknown_unit_is_a_409(
    client: TestClient, auth: dict[str, str]
) -> None:
    """The same movements uploaded in m and ×100 in cm: no difference once in one unit; beside a recording
    with no unit, no unit to convert to."""
    rows = cop_rows({"forward": 0.12, "left": 0.12})
    in_cm = [r | {"x": r["x"] * 100, "y": r["y"] * 100} for r in rows]
    plate_cm = {k: v * 100 for k, v in PLATE.items()}
    dems = [make_demonstrator(client, auth, name=n)["id"] for n in ("metres", "centimetres", "unknown")]
    for dem, samples, bounds, units in ((dems[0], rows, PLATE, "m"), (dems[1], in_cm, plate_cm, "cm")):
        body = {"bounds": bounds, "samples": samples, "units": units, "grid": {"width": 10, "height": 10}}
        created(client.post(f"/v1/demonstrators/{dem}/recordings", json=body, headers=auth))
    summary = created(client.get(f"/v1/demonstrators/{dems[1]}/motion-summary", headers=auth), 200)
    assert summary["unit"] == "cm" and summary["units"]["peak_reach"] == "cm"
    compared = created(
        client.post("/v1/motion-comparisons", json={"a": dems[0], "b": dems[1]}, headers=auth), 200
    )
    assert compared["unit"] in ("m", "cm")
    for row in compared["directions"]:
        assert abs(row["peak_reach_diff"]["mean"]) < 1e-3 * (100 if compared["unit"] == "cm" else 1), row
    make_recording(client, auth, dems[2])  # no units
    refused = client.post("/v1/motion-comparisons", json={"a": dems[0], "b": dems[2]}, headers=auth)
    assert refused.status_code == 409 and "cannot be put in one unit" in refused.json()["detail"]


def test_a_session_compared_with_itself_is_422_at_b(client: TestClient, auth: dict[str, str]) -> None:
    dem = make_demonstrator(client, auth)["id"]
    make_recording(client, auth, dem, WEAK)
    response = client.post("/v1/motion-comparisons", json={"a": dem, "b": dem}, headers=auth)
    assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == "/b"
