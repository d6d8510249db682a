"""Quiet standing over HTTP: standing uploads of every kind stored whole, their sway measures (the published
values of a public balance data set), trials compared by a metadata label in one length unit, and every real
C3D of the shared corpus giving a recording or the 422 its reason calls for."""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from service.files.c3d import read_c3d
from service.files.force_plates import in_plane_axes
from service.problems import Unprocessable
from tests.service.helpers import created, make_demonstrator
from tests.shared_data import shared_data

TOLERANCE = {
    "area95": ("COParea", 1e-6),
    "mean_velocity": ("COPvelo", 1e-6),
    "mean_frequency": ("COPmfreq", 1e-6),
}
"""Relative tolerance against the data set's own values, the COP stored as float32."""


def upload(
    client: TestClient, auth: dict[str, str], dem_id: str, name: str, data: bytes, **fields: Any
) -> Any:
    """POST a file with form fields (objects as JSON)."""
    form = {k: v if isinstance(v, str) else json.dumps(v) for k, v in fields.items()}
    return client.post(
        f"/v1/demonstrators/{dem_id}/recordings", files={"file": (name, data)}, data=form, headers=auth
    )


def sway(client: TestClient, auth: dict[str, str], rec_id: str, **query: Any) -> Any:
    """GET the recording's sway measures."""
    return client.get(f"/v1/recordings/{rec_id}/sway", params=query, headers=auth)


def random_walk(
    n: int = 1000, rate: float = 100.0, seed: int = 0, scale: float = 1.0
) -> list[dict[str, float]]:
    """A COP wandering about a point, as JSON samples (metres, times ``scale``)."""
    rng = np.random.default_rng(seed)
    xy = np.cumsum(rng.normal(0, 1e-4, (n, 2)), axis=0) * 0.5 * scale
    return [{"t": k / rate, "x": float(x), "y": float(y)} for k, (x, y) in enumerate(xy)]


def standing_trials(
    client: TestClient, auth: dict[str, str], trials: list[tuple[str, str | None, float]]
) -> tuple[str, list[str]]:
    """A demonstrator with 20-s standing trials of (vision, units, scale), trial k from seed k with its lengths
    times scale; its id and the recordings' ids."""
    dem = make_demonstrator(client, auth)
    url = f"/v1/demonstrators/{dem['id']}/recordings"
    ids = []
    for k, (vision, units, scale) in enumerate(trials):
        body: dict[str, Any] = {
            "protocol": "standing",
            "samples": random_walk(2000, seed=k, scale=scale),
            "metadata": {"vision": vision},
        } | ({"units": units} if units else {})
        ids.append(created(client.post(url, json=body, headers=auth))["id"])
    return dem["id"], ids


def sway_summary(client: TestClient, auth: dict[str, str], dem_id: str, by: str = "vision") -> Any:
    """GET the demonstrator's sway summary."""
    return client.get(f"/v1/demonstrators/{dem_id}/sway-summary", params={"by": by}, headers=auth)


def group_mean(summary: dict[str, Any], label: str, name: str) -> Any:
    """A group's mean of a measure in a sway summary."""
    return next(g for g in summary["groups"] if g["label"] == label)["measures"][name]["value"]


def problem(response: Any) -> dict[str, str]:
    """The first error of a 422."""
    assert response.status_code == 422, response.text
    return dict(response.json()["errors"][0])


def test_hbedb_trials_uploaded_as_standing_give_the_published_measures_and_compare_by_vision(
    client: TestClient, auth: dict[str, str]
) -> None:
    """Subject 1's twelve trials (eyes open/closed × firm/foam) as COP CSVs in cm with the lab's labels."""
    folder = shared_data("hbedb")
    with (folder / "reference-descriptors.tsv").open() as fh:
        trials = [row for row in csv.DictReader(fh, delimiter="\t") if row["Subject"] == "1"]
    dem = make_demonstrator(client, auth)
    for row in trials:
        data = np.loadtxt(folder / f"{row['Trial']}.txt", skiprows=1)
        text = "t,x,y\n" + "".join(f"{t:.3f},{x:.6f},{y:.6f}\n" for t, x, y in data[:, [0, 7, 8]])
        labels = {"vision": row["Vision"].lower(), "surface": row["Surface"].lower()}
        out = created(
            upload(
                client,
                auth,
                dem["id"],
                "trial.csv",
                text.encode(),
                protocol="standing",
                metadata=labels,
                units="cm",
            )
        )
        assert out["protocol"] == "standing" and out["metadata"] == labels and out["mdp_id"] is None
        assert out["tasks"] == [] and out["settings"]["bounds_from"] == "samples"
        measured = created(sway(client, auth, out["id"]), 200)
        assert measured["units"] == "cm" and measured["n_samples"] == 6000
        assert measured["duration_s"] == pytest.approx(60.0, rel=1e-9)
        assert measured["rate_hz"] == pytest.approx(100.0, rel=1e-9) and measured["not_estimated"] == {}
        for name, (column, tolerance) in TOLERANCE.items():
            assert measured["descriptors"][name] == pytest.approx(float(row[column]), rel=tolerance), name
        assert set(TOLERANCE) <= set(measured["methods"])
    summary = created(client.get(f"/v1/demonstrators/{dem['id']}/sway-summary?by=vision", headers=auth), 200)
    groups = {g["label"]: g for g in summary["groups"]}
    assert set(groups) == {"closed", "open"} and groups["open"]["n"] == 6
    expected_open = np.mean([float(r["COParea"]) for r in trials if r["Vision"] == "Open"])
    area = groups["open"]["measures"]["area95"]
    assert (
        area["value"] == pytest.approx(expected_open, rel=0.01) and area["low"] < area["value"] < area["high"]
    )
    (difference,) = summary["differences"]
    assert (difference["a"], difference["b"]) == ("closed", "open")
    romberg = summary["romberg"]["area95"]
    closed = groups["closed"]["measures"]["area95"]["value"]
    assert romberg["value"] == pytest.approx(closed / area["value"]) and romberg["low"] < romberg["high"]
    by_surface = created(
        client.get(f"/v1/demonstrators/{dem['id']}/sway-summary?by=surface", headers=auth), 200
    )
    assert {g["label"] for g in by_surface["groups"]} == {"firm", "foam"} and by_surface["romberg"] is None
    unknown = client.get(f"/v1/demonstrators/{dem['id']}/sway-summary?by=session", headers=auth)
    assert unknown.status_code == 409


def test_a_standing_json_upload_needs_no_bounds_and_cuts_nothing(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    url = f"/v1/demonstrators/{dem['id']}/recordings"
    samples = random_walk()
    out = created(client.post(url, json={"protocol": "standing", "samples": samples}, headers=auth))
    assert out["segments"] == {} and out["tasks"] == [] and out["mdp_id"] is None
    demonstrations = created(client.get(f"/v1/recordings/{out['id']}/demonstrations", headers=auth), 200)
    assert demonstrations["trajectories"] == []
    motion = client.get(f"/v1/demonstrators/{dem['id']}/motion-summary", headers=auth)
    assert motion.status_code == 409 and "standing trials have none" in motion.json()["detail"]
    assert sway(client, auth_b, out["id"]).status_code == 404
    movements = client.post(url, json={"samples": samples, "grid": {"width": 10, "height": 10}}, headers=auth)
    assert problem(movements)["pointer"] == "/bounds"
    with_grid = {"protocol": "standing", "samples": samples, "grid": {"width": 10, "height": 10}}
    assert problem(client.post(url, json=with_grid, headers=auth))["pointer"] == "/grid"
    still = [{"t": k / 100, "x": 0.0, "y": 0.0} for k in range(50)]
    error = problem(client.post(url, json={"protocol": "standing", "samples": still}, headers=auth))
    assert error["pointer"] == "/samples" and "never moves" in error["message"]


def test_sway_options_picture_and_spectra(client: TestClient, auth: dict[str, str]) -> None:
    dem = make_demonstrator(client, auth)
    url = f"/v1/demonstrators/{dem['id']}/recordings"
    rec = created(client.post(url, json={"protocol": "standing", "samples": random_walk()}, headers=auth))
    raw = created(sway(client, auth, rec["id"], spectra="true"), 200)
    assert raw["units"] is None and len(raw["spectra"]["frequencies"]) == len(raw["spectra"]["psd_x"]) == 251
    trimmed = created(sway(client, auth, rec["id"], trim_start_s=2, trim_end_s=1), 200)
    assert trimmed["n_samples"] == 700 and trimmed["options"]["trim_start_s"] == 2
    smooth = created(sway(client, auth, rec["id"], lowpass_hz=5), 200)
    assert smooth["descriptors"]["mean_velocity"] < raw["descriptors"]["mean_velocity"]
    assert problem(sway(client, auth, rec["id"], lowpass_hz=80))["pointer"] == "/lowpass_hz"
    assert problem(sway(client, auth, rec["id"], lowpass_hz=1e-9))["pointer"] == "/lowpass_hz"
    picture = sway(client, auth, rec["id"], format="png")
    assert picture.status_code == 200 and picture.headers["content-type"] == "image/png"
    assert picture.content.startswith(b"\x89PNG")


def test_a_standing_plate_csv_keeps_the_longest_loaded_stretch(
    client: TestClient, auth: dict[str, str]
) -> None:
    """Unloaded for 5 samples after 100 loaded: movements refuse it, standing keeps the 300 after the dip."""
    rng = np.random.default_rng(2)
    n = 405
    fz = np.full(n, 600.0)
    fz[100:105] = 3.0
    cop = np.cumsum(rng.normal(0, 1e-4, (n, 2)), axis=0)
    out = io.StringIO()
    out.write("t,Fx,Fy,Fz,Mx,My,Mz\n")
    for k in range(n):
        out.write(f"{k / 100:.2f},0,0,{fz[k]},{cop[k, 1] * fz[k]:.6f},{-cop[k, 0] * fz[k]:.6f},0\n")
    data = out.getvalue().encode()
    dem = make_demonstrator(client, auth)
    bounds = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
    moving = upload(client, auth, dem["id"], "f.csv", data, bounds=bounds, grid={"width": 10, "height": 10})
    assert problem(moving)["pointer"] == "/samples/100/fz"
    standing = created(upload(client, auth, dem["id"], "f.csv", data, protocol="standing"))
    assert standing["n_samples"] == 300 and standing["settings"]["units"] == "m"
    plate = standing["settings"]["plate"]
    assert plate["loaded_stretches_dropped"] == [{"start_s": 0.0, "stop_s": 0.99, "n_samples": 100}]
    assert plate["unloaded_samples"] == 105


RECORDED = {
    "BTS.c3d",
    "FP_Type3.c3d",
    "Kistler.c3d",
    "PiG__PiG_Calibration-FlatFoot-Full.c3d",
    "PiG__PiG_Motion-FlatFoot-Full.c3d",
    "Qualisys.c3d",
    "c3d.org__sample01__Eb015pi.c3d",
    "c3d.org__sample02__pc_real.c3d",
    "c3d.org__sample10__TYPE-2.C3D",
    "c3d.org__sample10__TYPE-4.C3D",
    "others__FunctionalStatic.c3d",
    "others__Gait.c3d",
}
"""Files of the corpus with a loaded plate: each must give a recording."""
NO_PLATFORM = {"C3DRotationExample.c3d", "Vicon.c3d"}
NO_FORCE_DATA = {"c3d.org__sample28__standing.C3D"}
STILL_COP = {"c3d.org__sample15__FP1.C3D"}
"""Its moments are all zero (a type-3 plate without sensor offsets): the COP sits at the plate's centre."""
UNLOADED = {
    "BTS.c3d": {2, 3, 6},
    "FP_Type1.c3d": {1, 2, 3, 4},
    "FP_Type3.c3d": {2},
    "others__FunctionalStatic.c3d": {3},
}
"""Plates of the corpus that never carry 20 N."""
REASONS = re.compile(
    r"no force platform|no force data|never loaded|never moves|is truncated|not a readable C3D|malformed"
)
"""The real reasons a C3D may be refused for."""


def finite_contract_measures(client: TestClient, auth: dict[str, str], rec_id: str) -> dict[str, Any]:
    """The recording's sway answer, after checking its contract measures are finite (the mean frequency of a
    stretch under 20 s with its caveat)."""
    measured = created(sway(client, auth, rec_id), 200)
    for name in TOLERANCE:
        value = measured["descriptors"][name]
        assert value is not None and math.isfinite(value) and value >= 0, (name, value)
    assert ("mean_frequency" in measured["caveats"]) == (measured["duration_s"] < 20), measured
    return measured


def corpus() -> list[Path]:
    """Every file of the shared C3D corpus."""
    return sorted(shared_data("c3d").iterdir())


def test_every_c3d_of_the_corpus_gives_a_standing_recording_per_loaded_plate_or_its_reason(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem = make_demonstrator(client, auth)
    files = corpus()
    assert len(files) >= 17
    for path in files:
        data = path.read_bytes()
        default = upload(client, auth, dem["id"], path.name, data, protocol="standing")
        known = path.name in NO_PLATFORM | NO_FORCE_DATA | STILL_COP or UNLOADED.get(path.name) == {
            1,
            2,
            3,
            4,
        }
        if default.status_code == 201:
            assert not known, path.name
            out = default.json()
            finite_contract_measures(client, auth, out["id"])
            plate = out["settings"]["plate"]
            assert plate["platform_choice"] == "most load" and plate["events"] == "ignore"
            n_plates = len(plate["platform_loads_ns"])
            for k in range(1, n_plates + 1):
                chosen = upload(
                    client, auth, dem["id"], path.name, data, protocol="standing", plate={"platform": k}
                )
                if k in UNLOADED.get(path.name, set()):
                    error = problem(chosen)
                    assert error["pointer"] == "/plate/platform" and "never loaded" in error["message"]
                else:
                    assert chosen.status_code == 201, (path.name, k, chosen.text)
                    finite_contract_measures(client, auth, chosen.json()["id"])
            continue
        error = problem(default)
        reason = REASONS.search(error["message"])
        assert reason is not None, (path.name, error)
        expected = {
            "no force platform": path.name in NO_PLATFORM,
            "no force data": path.name in NO_FORCE_DATA,
            "never moves": path.name in STILL_COP,
            "never loaded": path.name == "FP_Type1.c3d",
        }
        named = [words for words, yes in expected.items() if yes]
        assert named in ([], [reason[0]]), (
            path.name,
            error,
        )  # a file not listed here may fail for any reason


def test_the_quirks_of_real_c3d_files_are_read_and_recorded(client: TestClient, auth: dict[str, str]) -> None:
    folder = shared_data("c3d")
    dem = make_demonstrator(client, auth)

    def standing(name: str, **plate: Any) -> dict[str, Any]:
        fields: dict[str, Any] = {"protocol": "standing"} | ({"plate": plate} if plate else {})
        return created(upload(client, auth, dem["id"], name, (folder / name).read_bytes(), **fields))

    kistler = standing("Kistler.c3d")["settings"]["plate"]
    assert kistler["rate_hz"] == 600 and kistler["rate_source"] == "ANALOG:RATE"
    assert kistler["lab_axes"] == {"vertical": "y", "x": "z", "y": "x"}  # turned as x, y: not mirrored
    assert kistler["position_unit_read_as"] == "mm"
    qualisys = standing("Qualisys.c3d")["settings"]["plate"]
    assert qualisys["events"] == "ignore" and qualisys["n_events"] > 0
    data = (folder / "Qualisys.c3d").read_bytes()
    events = upload(
        client, auth, dem["id"], "q.c3d", data, protocol="standing", plate={"events": "instructions"}
    )
    error = problem(events)
    assert error["pointer"] == "/events/0/label" and 'plate.events = "ignore"' in error["message"]
    bts = standing("BTS.c3d")
    assert bts["settings"]["plate"]["lab_axes"] == {"vertical": "y", "x": "z", "y": "x"}
    # The file's own rate, not one read off its float32 times.
    assert created(sway(client, auth, bts["id"]), 200)["rate_hz"] == 1000
    half = upload(client, auth, dem["id"], "q.c3d", data[: len(data) // 2], protocol="standing")
    error = problem(half)
    assert error["pointer"] == "/file" and "is truncated" in error["message"]


def test_every_corpus_file_cut_to_half_its_bytes_is_a_422(client: TestClient, auth: dict[str, str]) -> None:
    dem = make_demonstrator(client, auth)
    for path in corpus():
        data = path.read_bytes()
        half = upload(client, auth, dem["id"], path.name, data[: len(data) // 2], protocol="standing")
        assert REASONS.search(problem(half)["message"]), path.name


def test_a_movements_recording_has_sway_measures_too(client: TestClient, auth: dict[str, str]) -> None:
    t = np.arange(0, 8, 0.01)
    reach = 0.15 * np.sin(np.pi * t / 2).clip(0) ** 2
    body = {
        "bounds": {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2},
        "grid": {"width": 20, "height": 20},
        "samples": [{"t": float(a), "x": float(b), "y": 0.0} for a, b in zip(t, reach, strict=True)],
    }
    dem = make_demonstrator(client, auth)
    rec = created(client.post(f"/v1/demonstrators/{dem['id']}/recordings", json=body, headers=auth))
    assert rec["protocol"] == "movements" and rec["segments"] == {"right": 2}
    measured = created(sway(client, auth, rec["id"]), 200)
    assert measured["descriptors"]["range_x"] == pytest.approx(0.15, rel=1e-3)
    assert measured["descriptors"]["mean_velocity"] == pytest.approx(4 * 0.15 / 8, rel=0.01)
    assert measured["descriptors"]["mean_frequency_y"] is None  # y never moves: no power to weigh


def test_trials_in_cm_and_mm_are_compared_in_one_unit(client: TestClient, auth: dict[str, str]) -> None:
    """One closed-eyes trial uploaded in mm, the same samples as another demonstrator's in cm: the same
    summary in cm (areas by the square), not a quotient 100 times off."""
    trials: list[tuple[str, str | None, float]] = [
        ("closed", "cm", 1.0),
        ("open", "cm", 1.0),
        ("open", "cm", 1.0),
    ]
    in_cm, _ = standing_trials(client, auth, [*trials, ("closed", "cm", 1.0)])
    mixed, _ = standing_trials(client, auth, [*trials, ("closed", "mm", 10.0)])
    reference = created(sway_summary(client, auth, in_cm), 200)
    summary = created(sway_summary(client, auth, mixed), 200)
    for name in ("area95", "mean_velocity", "rms", "mean_frequency"):
        expected = reference["romberg"][name]["value"]
        assert summary["romberg"][name]["value"] == pytest.approx(expected, rel=1e-5), name
        closed = group_mean(summary, "closed", name)
        assert closed == pytest.approx(group_mean(reference, "closed", name), rel=1e-5), name
    assert summary["unit"] == "cm" and summary["units"] == ["cm", "mm"]
    all_mm, _ = standing_trials(client, auth, [("closed", "mm", 10.0), ("open", "m", 0.01)])
    assert created(sway_summary(client, auth, all_mm), 200)["unit"] == "mm"  # a tie: the finer unit


def test_a_unit_spelt_out_is_stored_and_compared_as_its_symbol(
    client: TestClient, auth: dict[str, str]
) -> None:
    """``centimetres`` and ``Millimeter`` are cm and mm, as in a CSV header: one unit per trial, not a 409."""
    dem, ids = standing_trials(
        client, auth, [("closed", "centimetres", 1.0), ("open", "cm", 1.0), ("open", "Millimeter", 10.0)]
    )
    listed = client.get(f"/v1/demonstrators/{dem}/recordings", headers=auth).json()["data"]
    assert {r["id"]: r["settings"]["units"] for r in listed} == dict(
        zip(ids, ["cm", "cm", "mm"], strict=True)
    )
    summary = created(sway_summary(client, auth, dem), 200)
    assert summary["unit"] == "cm" and summary["units"] == ["cm", "mm"]


def test_trials_with_and_without_a_unit_are_a_409_naming_those_without(
    client: TestClient, auth: dict[str, str]
) -> None:
    dem, ids = standing_trials(client, auth, [("closed", "cm", 1.0), ("open", None, 1.0)])
    answer = sway_summary(client, auth, dem)
    assert answer.status_code == 409 and answer.headers["content-type"].startswith("application/problem+json")
    body = answer.json()
    assert ids[1] in body["detail"] and "`units`" in body["detail"]
    assert [e["recording_id"] for e in body["errors"]] == [ids[1]]
    dem, ids = standing_trials(client, auth, [("closed", "cm", 1.0), ("open", "in", 1.0)])
    body = sway_summary(client, auth, dem).json()
    assert body["status"] == 409 and [e["recording_id"] for e in body["errors"]] == [ids[1]]


def test_the_romberg_quotient_leaves_out_the_ellipse_angle(client: TestClient, auth: dict[str, str]) -> None:
    dem, _ = standing_trials(client, auth, [("closed", "cm", 1.0), ("open", "cm", 1.0)])
    summary = created(sway_summary(client, auth, dem), 200)
    assert (
        "ellipse_angle" in summary["groups"][0]["measures"]
        and "ellipse_angle" in summary["differences"][0]["measures"]
    )
    assert "ellipse_angle" not in summary["romberg"] and "area95" in summary["romberg"]


def test_a_trial_under_20_s_answers_its_frequency_measures_with_a_caveat(
    client: TestClient, auth: dict[str, str]
) -> None:
    """The 8 samples (7 ms) of a C3D test file, and a 10-s trial: every contract measure, the frequencies
    flagged."""
    dem = make_demonstrator(client, auth)
    data = (shared_data("c3d") / "FP_Type3.c3d").read_bytes()
    plate = created(upload(client, auth, dem["id"], "FP_Type3.c3d", data, protocol="standing"))
    measured = created(sway(client, auth, plate["id"]), 200)
    assert measured["n_samples"] == 8 and measured["descriptors"]["area95"] > 0
    frequencies = ("mean_frequency", "mean_frequency_x", "mean_frequency_y", "f95", "f95_x", "f95_y")
    assert all(measured["descriptors"][name] > 0 for name in frequencies)
    assert set(measured["caveats"]) == set(frequencies) and measured["not_estimated"] == {}
    assert "shorter than the 20 s" in measured["caveats"]["mean_frequency"]
    url = f"/v1/demonstrators/{dem['id']}/recordings"
    for vision, n in (("open", 1000), ("closed", 2000)):
        body = {"protocol": "standing", "samples": random_walk(n), "metadata": {"vision": vision}}
        created(client.post(url, json=body, headers=auth))
    summary = created(sway_summary(client, auth, dem["id"]), 200)
    groups = {g["label"]: g["measures"] for g in summary["groups"]}
    assert groups["open"]["mean_frequency"]["value"] > 0 and groups["closed"]["mean_frequency"]["value"] > 0
    assert summary["romberg"]["mean_frequency"]["value"] > 0 and summary["romberg"]["area95"]["value"] > 0
    assert summary["not_estimated"] == {} and summary["unlabelled"] == [plate["id"]]


def test_a_c3d_whose_cop_leaves_its_plate_says_how_much_beside_every_measure(
    client: TestClient, auth: dict[str, str]
) -> None:
    """A gait trial's COP runs past a 0.914 × 0.610 m plate (heel strike, toe off); a quiet one stays on it."""
    dem = make_demonstrator(client, auth)
    folder = shared_data("c3d")
    gait = created(
        upload(
            client, auth, dem["id"], "g.c3d", (folder / "others__Gait.c3d").read_bytes(), protocol="standing"
        )
    )
    assert gait["settings"]["plate"]["plate_half_size_m"] == [0.4572, 0.3048]
    assert 0 < gait["settings"]["plate"]["off_plate_fraction"] < 0.05
    caveat = created(sway(client, auth, gait["id"]), 200)["caveats"]["samples"]
    assert "off the plate (0.914 × 0.61 m)" in caveat and caveat.startswith("1.1%")
    quiet = (folder / "Kistler.c3d").read_bytes()
    still = created(upload(client, auth, dem["id"], "q.c3d", quiet, protocol="standing"))
    assert still["settings"]["plate"]["off_plate_fraction"] == 0
    assert "samples" not in created(sway(client, auth, still["id"]), 200)["caveats"]


def test_the_corners_of_every_real_plate_say_its_lab_vertical_points_up() -> None:
    """What `in_plane_axes` assumes, on the corpus: C3D numbers a plate's corners so that its own x × y points
    into the floor, and in every file that is down the lab's vertical axis (plates with corners no real plate
    has, like FP_Type1's, are left out)."""
    checked = 0
    for path in corpus():
        try:
            platforms = read_c3d(path.read_bytes()).platforms
        except Unprocessable:  # the corpus's unreadable files
            continue
        for p in platforms:
            corners = p.corners
            x, y = corners[:, 0] - corners[:, 1], corners[:, 0] - corners[:, 3]
            up = -np.cross(x, y)
            if not np.isfinite(up).all() or np.linalg.norm(up) == 0 or np.abs(corners).max() > 1e5:
                continue
            vertical = int(np.argmin(np.ptp(corners, axis=1)))
            assert up[vertical] > 0.99 * np.linalg.norm(up), (path.name, up)
            a, b = np.eye(3)[in_plane_axes(vertical)]
            assert np.cross(a, b)[vertical] == 1
            checked += 1
    assert checked >= 25
