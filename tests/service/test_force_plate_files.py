"""Force-plate files on the recordings route: C3D files built here with ezc3d and CSVs of forces and moments
become the same COP (metres, plate centre, patient axes) as the samples they were made from; files without a
usable plate, channel or column are 422s naming the problem, and store nothing."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import ezc3d
import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_client import Client
from metairl_engine.motion.recording import canonical_instruction
from service.files import c3d
from service.store.models.recordings import Recording as RecordingRow
from service.store.recordings import load_recording
from tests.service.helpers import created, make_demonstrator

RATE = 50.0
GRID = {"width": 10, "height": 10}
PLATE = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
CENTRE_MM = (500.0, 300.0)
"""Where the C3D's plate lies in the lab."""


def cop_path(repetitions: int = 2) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """t, (N, 2) COP in metres and the instruction of each sample: out and back forward, then left."""
    xy: list[tuple[float, float]] = []
    instruction: list[str] = []
    for name, (ux, uy) in (("forward", (0.0, 1.0)), ("left", (-1.0, 0.0))):
        for _ in range(repetitions):
            profile = np.concatenate(
                [np.zeros(30), 0.12 * 0.5 * (1 - np.cos(2 * np.pi * np.arange(60) / 60))]
            )
            xy += [(a * ux, a * uy) for a in profile]
            instruction += ["rest"] * 30 + [name] * 60
    xy += [(0.0, 0.0)] * 30
    instruction += ["rest"] * 30
    return np.arange(len(xy)) / RATE, np.array(xy), instruction


T, COP, INSTRUCTION = cop_path()


def int_parameter(c: Any, group: str, name: str, values: list[int], shape: list[int]) -> None:
    """Add an INT parameter (ezc3d's `add_parameter` stores Python ints as floats, which FORCE_PLATFORM
    may not hold)."""
    param = ezc3d.ezc3d.Parameter(name)
    param.set(ezc3d.ezc3d.VecInt(values), shape)
    c["parameters"].add_parameter(group, param)


def c3d_bytes(
    tmp_path: Path,
    cop_m: np.ndarray,
    *,
    fz: np.ndarray | float = 600.0,
    events: Sequence[tuple[str, float]] = (),
    platforms: int = 1,
    channels: int | None = None,
    vertical: str = "z",
) -> bytes:
    """A C3D at `RATE` Hz, analogs only, whose platform `platforms` (type 2, corners 400 mm square about
    `CENTRE_MM`, units mm and N) carries the load `fz` at `cop_m` (metres about its centre); the others carry
    nothing. `channels` fewer analog channels than the plates need breaks FORCE_PLATFORM:CHANNEL. `vertical`
    ``"y"`` writes the same plate in a y-up lab, the z-up lab turned so that its (x, y, z) is (z, x, y)."""
    n = len(cop_m)
    fz = np.broadcast_to(np.asarray(fz, dtype=np.float64), (n,))
    shear = np.column_stack([np.full(n, 8.0), np.full(n, -5.0)])
    loaded = np.column_stack([shear, fz, cop_m[:, 1] * 1000 * fz, -cop_m[:, 0] * 1000 * fz, np.zeros(n)])
    analogs = np.concatenate([np.zeros((n, 6 * max(platforms - 1, 0))), loaded], axis=1)[:, :channels]
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [RATE]
    c["parameters"]["POINT"]["LABELS"]["value"] = []
    c["data"]["points"] = np.zeros((4, 0, n))
    c["parameters"]["ANALOG"]["RATE"]["value"] = [RATE]
    c["parameters"]["ANALOG"]["LABELS"]["value"] = [f"ch{k}" for k in range(analogs.shape[1])]
    c["data"]["analogs"] = analogs.T[np.newaxis]
    c.add_parameter("POINT", "UNITS", ["mm"])
    if platforms:
        int_parameter(c, "FORCE_PLATFORM", "USED", [platforms], [1])
        int_parameter(c, "FORCE_PLATFORM", "TYPE", [2] * platforms, [platforms])
        int_parameter(c, "FORCE_PLATFORM", "CHANNEL", list(range(1, 6 * platforms + 1)), [6, platforms])
        c.add_parameter("FORCE_PLATFORM", "UNITS", ["N"])
        cx, cy = CENTRE_MM
        square = [
            [cx + 200, cy + 200, 0],
            [cx - 200, cy + 200, 0],
            [cx - 200, cy - 200, 0],
            [cx + 200, cy - 200, 0],
        ]
        lab = np.array(square, dtype=np.float64).T[[0, 1, 2] if vertical == "z" else [1, 2, 0]]
        corners = np.repeat(lab[:, :, np.newaxis], platforms, axis=2)
        c.add_parameter("FORCE_PLATFORM", "CORNERS", corners)
        c.add_parameter("FORCE_PLATFORM", "ORIGIN", np.zeros((3, platforms)))
    for label, time in events:
        c.add_event([0, time], label=label)
    path = tmp_path / "session.c3d"
    c.write(str(path))
    return path.read_bytes()


def instruction_events(t: np.ndarray, instruction: list[str]) -> list[tuple[str, float]]:
    """An event at every change of instruction, half a sample early (event times are float32 in a C3D)."""
    return [
        (name, float(t[k]) - 0.5 / RATE)
        for k, name in enumerate(instruction)
        if k == 0 or instruction[k - 1] != name
    ][1:]  # the recording starts at rest without an event


def post_file(
    client: TestClient, auth: dict[str, str], dem_id: str, data: bytes, name: str, **plate: Any
) -> Any:
    """Upload a file onto a 10×10 velocity grid (with `plate` options if any)."""
    form = {"bounds": json.dumps(PLATE), "grid": json.dumps(GRID)}
    form |= {"plate": json.dumps(plate)} if plate else {}
    return client.post(
        f"/v1/demonstrators/{dem_id}/recordings", files={"file": (name, data)}, data=form, headers=auth
    )


def stored(app: FastAPI, recording_id: str) -> Any:
    """The engine `Recording` the upload stored."""
    with app.state.sessionmaker() as session:
        return load_recording(session, session.get_one(RecordingRow, recording_id))[0]


def problem(response: Any, status: int = 422) -> list[dict[str, str]]:
    """The errors of a problem+json answer."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    return list(response.json()["errors"])


def assert_nothing_stored(client: TestClient, auth: dict[str, str], dem_id: str) -> None:
    """No recording, task or MDP came of the upload."""
    assert client.get(f"/v1/demonstrators/{dem_id}/recordings", headers=auth).json()["data"] == []
    assert client.get(f"/v1/demonstrators/{dem_id}/tasks", headers=auth).json()["data"] == []
    assert client.get("/v1/mdps", headers=auth).json()["data"] == []


def test_a_c3d_recording_stores_the_plates_cop_in_metres_about_its_centre_with_its_events(
    app: FastAPI, client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    """Stepping on (10 samples) and off (5) the plate is cut away; the rest is the COP written, in metres."""
    cop = np.concatenate([np.zeros((10, 2)), COP, np.zeros((5, 2))])
    fz = np.concatenate([np.zeros(10), np.full(len(COP), 600.0), np.full(5, 3.0)])
    t = np.arange(len(cop)) / RATE
    events = instruction_events(t, ["rest"] * 10 + INSTRUCTION + ["rest"] * 5)
    dem = make_demonstrator(client, auth)
    out = created(post_file(client, auth, dem["id"], c3d_bytes(tmp_path, cop, fz=fz, events=events), "s.c3d"))
    assert out["format"] == "c3d" and out["segments"] == {"forward": 2, "left": 2}
    assert out["n_samples"] == len(COP)
    assert out["settings"]["plate"] == {
        "rate_hz": RATE,
        "rate_source": "header",
        "position_unit": "mm",
        "position_unit_read_as": "mm",
        "position_unit_reason": "the file's unit",
        "lab_axes": {"vertical": "z", "x": "x", "y": "y"},
        "force_unit": "N",
        "axes": {"x": "right", "y": "forward"},
        "min_fz": 20.0,
        "platform": 1,
        "platform_choice": "most load",
        "platform_loads_ns": [pytest.approx(fz.sum() / RATE, abs=1e-3)],
        "plate_half_size_m": [0.2, 0.2],
        "off_plate_fraction": 0.0,
        "events": "instructions",
        "n_events": len(events),
        "unloaded_samples": 15,
    }
    rec = stored(app, out["id"])
    np.testing.assert_allclose(np.column_stack([rec.x, rec.y]), COP, atol=1e-5)
    np.testing.assert_allclose(rec.t, t[10:-5], atol=1e-5)
    assert rec.instruction.tolist() == [canonical_instruction(i) for i in INSTRUCTION]


def test_a_c3d_from_a_y_up_lab_stores_the_same_cop_as_from_a_z_up_one_not_its_mirror_image(
    app: FastAPI, client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    """The lab turned (a rotation, no reflection) leaves the patient's sway as it was: lab z and x are the
    plate's x and y under y up, as lab x and y are under z up."""
    dem = make_demonstrator(client, auth)
    z_up, y_up = (
        created(post_file(client, auth, dem["id"], c3d_bytes(tmp_path, COP, vertical=v), f"{v}.c3d"))
        for v in ("z", "y")
    )
    assert z_up["settings"]["plate"]["lab_axes"] == {"vertical": "z", "x": "x", "y": "y"}
    assert y_up["settings"]["plate"]["lab_axes"] == {"vertical": "y", "x": "z", "y": "x"}
    for out in (z_up, y_up):
        rec = stored(app, out["id"])
        np.testing.assert_allclose(np.column_stack([rec.x, rec.y]), COP, atol=1e-5)


def test_a_c3d_and_the_same_samples_as_json_make_the_same_demonstrations(
    client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    samples = [
        {"t": float(t), "x": float(x), "y": float(y), "instruction": i}
        for t, (x, y), i in zip(T, COP, INSTRUCTION, strict=True)
    ]
    body = {"bounds": PLATE, "grid": GRID, "samples": samples}
    dem_json, dem_c3d = make_demonstrator(client, auth), make_demonstrator(client, auth)
    by_json = created(client.post(f"/v1/demonstrators/{dem_json['id']}/recordings", json=body, headers=auth))
    data = c3d_bytes(tmp_path, COP, events=instruction_events(T, INSTRUCTION))
    by_c3d = created(post_file(client, auth, dem_c3d["id"], data, "session.c3d"))
    assert [(t["label"], t["n_steps"]) for t in by_c3d["tasks"]] == [
        (t["label"], t["n_steps"]) for t in by_json["tasks"]
    ]


def test_the_plate_option_picks_one_of_several_platforms_and_without_it_the_most_loaded(
    app: FastAPI, client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    data = c3d_bytes(tmp_path, COP, platforms=2)
    dem = make_demonstrator(client, auth)
    for given in ({"platform": 2}, {}):
        out = created(post_file(client, auth, dem["id"], data, "two.c3d", **given))
        rec = stored(app, out["id"])
        np.testing.assert_allclose(np.column_stack([rec.x, rec.y]), COP, atol=1e-5)
        assert rec.instruction is None and set(out["segments"]) == {"forward", "left"}  # nearest direction
        assert out["settings"]["plate"]["platform"] == 2
        assert out["settings"]["plate"]["platform_choice"] == ("given" if given else "most load")
    errors = problem(post_file(client, auth, dem["id"], data, "two.c3d", platform=3))
    assert errors[0]["pointer"] == "/plate/platform" and "has 2 force platforms" in errors[0]["message"]
    errors = problem(post_file(client, auth, dem["id"], data, "two.c3d", platform=1))  # carries nothing
    assert errors[0]["pointer"] == "/plate/platform" and "never loaded" in errors[0]["message"]


BAD_C3D: list[tuple[str, dict[str, Any], str, str]] = [
    ("no force platform", {"platforms": 0}, "/file", "has no force platform"),
    ("channels past the analogs", {"channels": 2}, "/file", "FORCE_PLATFORM parameters or channels"),
    ("no load on the plate", {"fz": 0.0}, "/samples", "the plate was never loaded"),
    (
        "unloaded in the middle",
        {"fz": np.r_[np.full(50, 600.0), np.zeros(5), np.full(len(COP) - 55, 600.0)]},
        "/samples/50/fz",
        "between loaded samples",
    ),
    (
        "unknown event",
        {"events": [("forward", 0.1), ("Foot Strike", 0.5)]},
        "/events/1/label",
        "'Foot Strike'",
    ),
]


@pytest.mark.parametrize(("build", "pointer", "words"), [b[1:] for b in BAD_C3D], ids=[b[0] for b in BAD_C3D])
def test_a_c3d_without_a_usable_plate_is_422_naming_the_problem_and_stores_nothing(
    client: TestClient, auth: dict[str, str], tmp_path: Path, build: dict[str, Any], pointer: str, words: str
) -> None:
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], c3d_bytes(tmp_path, COP, **build), "bad.c3d"))
    assert errors[0]["pointer"] == pointer and words in errors[0]["message"], errors
    assert_nothing_stored(client, auth, dem["id"])


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"t,x,y\n0,0,0\n", "is not a C3D file"),
        (b"\x02P" + bytes(600), "is not a readable C3D file"),
    ],
    ids=["text named .c3d", "a C3D header and nothing else"],
)
def test_a_file_that_is_no_readable_c3d_is_422_naming_the_file(
    client: TestClient, auth: dict[str, str], data: bytes, words: str
) -> None:
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], data, "session.c3d"))
    assert errors[0]["pointer"] == "/file" and words in errors[0]["message"], errors


@pytest.mark.parametrize(
    ("reader", "timeout_s", "words"),
    [
        (("-c", "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)"), 60.0, "stopped on signal 11"),
        (("-c", "import time; time.sleep(30)"), 0.5, "took longer than 0.5 s"),
    ],
    ids=["crash", "hang"],
)
def test_a_reader_that_crashes_or_hangs_is_a_422_and_the_api_answers_on(
    client: TestClient,
    auth: dict[str, str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    reader: tuple[str, ...],
    timeout_s: float,
    words: str,
) -> None:
    """ezc3d crashes (SIGSEGV) or loops on some malformed files: the child process takes the blow."""
    monkeypatch.setattr(c3d, "READER", reader)
    monkeypatch.setattr(c3d, "TIMEOUT_S", timeout_s)
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], c3d_bytes(tmp_path, COP), "session.c3d"))
    assert errors[0]["pointer"] == "/file" and words in errors[0]["message"], errors
    assert client.get("/healthz").status_code == 200


def plate_csv(
    *,
    to_plate: list[list[int]],
    z_up: bool,
    fz: float,
    per_metre: float,
    depth: float,
    times: bool = False,
    instructions: bool = False,
) -> str:
    """The forces and moments that a load `fz` with shear acting at `COP` puts on a plate whose (x, y) are
    the patient's (right, forward) @ `to_plate`, its origin `depth` below the surface, moments in N × (metre /
    `per_metre`); optionally with columns t and instruction."""
    plate_xy = COP @ np.array(to_plate) * per_metre
    point = np.column_stack([plate_xy, np.full(len(COP), depth if z_up else -depth)])
    force = np.column_stack([np.full(len(COP), 12.0), np.full(len(COP), -7.0), np.full(len(COP), fz)])
    moment = np.cross(point, force)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["Fx", "Fy", "Fz", "Mx", "My", "Mz", *["t"] * times, *["instruction"] * instructions])
    for k in range(len(COP)):
        extra = [f"{T[k]:.4f}"] * times + [INSTRUCTION[k]] * instructions
        writer.writerow([f"{v:.6f}" for v in (*force[k], *moment[k])] + extra)
    return out.getvalue()


CONVENTIONS: list[tuple[str, dict[str, Any], dict[str, Any]]] = [
    (
        "AMTI frame facing forward: z down, Fz > 0, N·mm, origin 40 mm deep",
        {"to_plate": [[-1, 0], [0, 1]], "z_up": False, "fz": 600.0, "per_metre": 1000.0, "depth": 40.0},
        {"axes": {"x": "left", "y": "forward"}, "moment_unit": "Nmm", "origin_depth": 40.0, "rate_hz": RATE},
    ),
    (
        "lab frame: z up, Fz < 0, N·m, origin 1 cm deep, t column",
        {
            "to_plate": [[1, 0], [0, 1]],
            "z_up": True,
            "fz": -600.0,
            "per_metre": 1.0,
            "depth": 0.01,
            "times": True,
        },
        {"origin_depth": 0.01},
    ),
    (
        "x forward, y left: z up, N·cm",
        {"to_plate": [[0, -1], [1, 0]], "z_up": True, "fz": 600.0, "per_metre": 100.0, "depth": 0.0},
        {"axes": {"x": "forward", "y": "left"}, "moment_unit": "Ncm", "rate_hz": RATE},
    ),
]


@pytest.mark.parametrize(("make", "plate"), [c[1:] for c in CONVENTIONS], ids=[c[0] for c in CONVENTIONS])
def test_a_plate_csv_gives_the_cop_from_moments_over_fz_in_the_declared_frame(
    app: FastAPI, client: TestClient, auth: dict[str, str], make: dict[str, Any], plate: dict[str, Any]
) -> None:
    dem = make_demonstrator(client, auth)
    out = created(post_file(client, auth, dem["id"], plate_csv(**make).encode(), "plate.csv", **plate))
    assert out["format"] == "forces" and out["n_samples"] == len(COP)
    assert out["settings"]["plate"]["unloaded_samples"] == 0 and "platform" not in out["settings"]["plate"]
    rec = stored(app, out["id"])
    np.testing.assert_allclose(np.column_stack([rec.x, rec.y]), COP, atol=1e-6)
    np.testing.assert_allclose(rec.t, T, atol=1e-9)
    assert set(out["segments"]) == {"forward", "left"}


def test_a_plate_csv_carries_its_instructions_like_a_cop_csv(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    text = plate_csv(**CONVENTIONS[1][1] | {"instructions": True})
    dem = make_demonstrator(client, auth)
    out = created(post_file(client, auth, dem["id"], text.encode(), "plate.csv", origin_depth=0.01))
    rec = stored(app, out["id"])
    assert rec.instruction.tolist() == [canonical_instruction(i) for i in INSTRUCTION]


def test_a_plate_csv_missing_fz_is_422_naming_the_column(client: TestClient, auth: dict[str, str]) -> None:
    text = plate_csv(**CONVENTIONS[1][1]).replace("Fx,Fy,Fz,", "Fx,Fy,Fvert,", 1)
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], text.encode(), "plate.csv"))
    assert "missing fz" in errors[0]["message"], errors
    assert_nothing_stored(client, auth, dem["id"])


def test_a_plate_unloaded_between_loaded_samples_is_422_naming_sample_and_line(
    client: TestClient, auth: dict[str, str]
) -> None:
    lines = plate_csv(**CONVENTIONS[1][1]).splitlines()
    for k in range(40, 46):  # samples 40 … 45 on lines 42 … 47
        cells = lines[k + 1].split(",")
        cells[2] = "1.5"
        lines[k + 1] = ",".join(cells)
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], "\n".join(lines).encode(), "plate.csv"))
    assert errors[0]["pointer"] == "/samples/40/fz", errors
    assert "(6 such samples)" in errors[0]["message"] and "CSV line 42" in errors[0]["message"]


MISFITS: list[tuple[str, str | None, dict[str, Any], str, str]] = [
    (
        "plate options for a COP CSV",
        "t,x,y\n0,0,0\n0.1,0,0.01\n",
        {"min_fz": 10},
        "/plate",
        "force-plate files only",
    ),
    ("a rate and a t column", None, {"rate_hz": 100}, "/plate/rate_hz", "has a t column"),
    ("neither rate nor t column", "Fx,Fy,Fz,Mx,My,Mz\n0,0,600,0,0,0\n", {}, "/plate/rate_hz", "no t column"),
    ("a platform for a CSV", None, {"platform": 2}, "/plate/platform", "C3D files only"),
    ("axes along one line", None, {"axes": {"x": "left", "y": "right"}}, "/plate/axes", "perpendicular"),
    ("an unknown option", None, {"units": "mm"}, "/plate/units", ""),
]


@pytest.mark.parametrize(
    ("text", "plate", "pointer", "words"), [m[1:] for m in MISFITS], ids=[m[0] for m in MISFITS]
)
def test_plate_options_that_do_not_fit_the_file_are_422(
    client: TestClient,
    auth: dict[str, str],
    text: str | None,
    plate: dict[str, Any],
    pointer: str,
    words: str,
) -> None:
    data = (text or plate_csv(**CONVENTIONS[1][1])).encode()
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], data, "upload.csv", **plate))
    assert errors[0]["pointer"] == pointer and words in errors[0]["message"], errors


def test_csv_options_for_a_c3d_are_422(client: TestClient, auth: dict[str, str], tmp_path: Path) -> None:
    dem = make_demonstrator(client, auth)
    errors = problem(post_file(client, auth, dem["id"], c3d_bytes(tmp_path, COP), "s.c3d", rate_hz=100))
    assert (
        errors[0]["pointer"] == "/plate/rate_hz"
        and "CSV files of forces and moments only" in errors[0]["message"]
    )


def test_the_lab_client_uploads_a_c3d_file_and_a_plate_csv(
    client: TestClient, auth: dict[str, str], tmp_path: Path
) -> None:
    client.headers.update(auth)
    lab = Client(client)
    dem_id = lab.create_demonstrator(name="force-plate subject")
    mdp_id = lab.create_mdp({"kind": "grid", "name": "plate", "velocity": True, "gamma": 0.9, **GRID})
    path = tmp_path / "session.c3d"
    path.write_bytes(c3d_bytes(tmp_path, COP, events=instruction_events(T, INSTRUCTION)))
    from_c3d = lab.upload_recording(dem_id, path, mdp_id=mdp_id, bounds=PLATE, name="session 1")
    assert from_c3d["format"] == "c3d" and from_c3d["segments"] == {"forward": 2, "left": 2}
    text = plate_csv(**CONVENTIONS[0][1]).encode()
    from_csv = lab.upload_recording(dem_id, text, mdp_id=mdp_id, bounds=PLATE, plate=CONVENTIONS[0][2])
    assert from_csv["format"] == "forces" and not any(t["created"] for t in from_csv["tasks"])
