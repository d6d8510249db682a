"""COP recordings over HTTP: per-direction tasks and demonstrations, joining, CSV = JSON, 422s naming the
sample (and CSV line), all-or-nothing uploads and tenancy."""

from __future__ import annotations

import csv
import io
import json
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_engine.motion.recording import DiscretiseSettings, Recording, demonstrations
from metairl_engine.sim.patient import PatientSettings, simulate_patient
from service.store.loaders import load_trajectories
from service.store.models.demonstrators import Demonstrator
from service.store.recordings import lock_demonstrator
from service.store.tasks import create_task
from tests.service.helpers import created, make_demonstrator, make_mdp

REPO = Path(__file__).resolve().parents[2]
SIZE = 20
DIRECTIONS = ("forward", "right", "backward left")
PLATE = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
Rows = list[dict[str, Any]]


@pytest.fixture(scope="module")
def session_rec() -> Recording:
    """A short stimulated session on a 20×20 plate grid: 3 directions × 2 repetitions."""
    patient = simulate_patient(PatientSettings(width=SIZE, height=SIZE, repetitions=2, directions=DIRECTIONS))
    return patient.sessions["stimulated"]


@pytest.fixture(scope="module")
def rows(session_rec: Recording) -> Rows:
    """The session as JSON sample rows."""
    assert session_rec.instruction is not None
    return [
        {"t": float(t), "x": float(x), "y": float(y), "instruction": str(i)}
        for t, x, y, i in zip(
            session_rec.t, session_rec.x, session_rec.y, session_rec.instruction, strict=True
        )
    ]


def to_csv(samples: Rows) -> str:
    """Sample rows as CSV text with header t,x,y,instruction."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=["t", "x", "y", "instruction"], lineterminator="\n")
    writer.writeheader()
    writer.writerows(samples)
    return out.getvalue()


def velocity_grid(client: TestClient, auth: dict[str, str]) -> str:
    """A 20×20 velocity-grid MDP of the lab; its id."""
    body = {"kind": "grid", "name": "plate", "width": SIZE, "height": SIZE, "velocity": True, "gamma": 0.9}
    return str(created(client.post("/v1/mdps", json=body, headers=auth))["id"])


def post_json(client: TestClient, auth: dict[str, str], dem_id: str, samples: Rows, **options: Any) -> Any:
    """Upload a recording as JSON (NaN written as the literal JavaScript parsers and Python's json accept)."""
    body = json.dumps({"bounds": PLATE, "samples": samples} | options)
    headers = auth | {"Content-Type": "application/json"}
    return client.post(f"/v1/demonstrators/{dem_id}/recordings", content=body, headers=headers)


def post_csv(client: TestClient, auth: dict[str, str], dem_id: str, text: str, **fields: str) -> Any:
    """Upload a recording as a CSV file with form fields (bounds as JSON)."""
    data = {"bounds": json.dumps(PLATE)} | fields
    return client.post(
        f"/v1/demonstrators/{dem_id}/recordings",
        files={"file": ("session.csv", text.encode())},
        data=data,
        headers=auth,
    )


def tasks_of(client: TestClient, auth: dict[str, str], dem_id: str) -> dict[str, dict[str, Any]]:
    """The demonstrator's tasks by name."""
    listed = client.get(f"/v1/demonstrators/{dem_id}/tasks", headers=auth).json()["data"]
    return {t["name"]: t for t in listed}


def test_upload_creates_one_task_per_instructed_direction(
    client: TestClient, auth: dict[str, str], session_rec: Recording, rows: Rows
) -> None:
    expected = demonstrations(session_rec, discretise_settings=DiscretiseSettings(width=SIZE, height=SIZE))
    assert {label: len(t) for label, t in expected.by_label.items()} == dict.fromkeys(DIRECTIONS, 2)
    dem = make_demonstrator(client, auth)
    mdp_id = velocity_grid(client, auth)
    out = created(post_json(client, auth, dem["id"], rows, mdp_id=mdp_id, name="stimulated"))
    assert out["id"].startswith("rec_") and out["mdp_id"] == mdp_id and not out["mdp_created"]
    assert out["segments"] == dict.fromkeys(DIRECTIONS, 2)
    assert out["n_samples"] == len(rows) and out["format"] == "json" and out["dropped_samples"] > 0
    assert all(t["created"] for t in out["tasks"])
    tasks = tasks_of(client, auth, dem["id"])
    assert set(tasks) == set(DIRECTIONS)
    for t in out["tasks"]:
        assert tasks[t["label"]]["id"] == t["task_id"] and tasks[t["label"]]["mdp_id"] == mdp_id
        assert (tasks[t["label"]]["n_trajectories"], tasks[t["label"]]["n_steps"]) == (2, t["n_steps"])
        assert t["n_steps"] == sum(len(tr.actions) for tr in expected.by_label[t["label"]])
    listed = client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"]
    assert [r["id"] for r in listed] == [out["id"]] and listed[0]["tasks"] == out["tasks"]


def test_reupload_joins_the_existing_tasks(client: TestClient, auth: dict[str, str], rows: Rows) -> None:
    dem = make_demonstrator(client, auth)
    mdp_id = velocity_grid(client, auth)
    first = created(post_json(client, auth, dem["id"], rows, mdp_id=mdp_id))
    second = created(post_json(client, auth, dem["id"], rows, mdp_id=mdp_id))
    assert not any(t["created"] for t in second["tasks"])
    assert [t["task_id"] for t in second["tasks"]] == [t["task_id"] for t in first["tasks"]]
    tasks = tasks_of(client, auth, dem["id"])
    assert len(tasks) == 3 and all(t["n_trajectories"] == 4 for t in tasks.values())
    assert len(client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"]) == 2


def test_concurrent_uploads_with_a_new_label_join_one_task(
    app: FastAPI, client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    """Upload B waits while another transaction holding the demonstrator creates "forward", then joins it."""
    dem = make_demonstrator(client, auth)
    mdp_id = velocity_grid(client, auth)
    responses: list[Any] = []
    with app.state.sessionmaker() as first:
        lock_demonstrator(first, dem["id"])
        upload = threading.Thread(
            target=lambda: responses.append(post_json(client, auth, dem["id"], rows, mdp_id=mdp_id))
        )
        upload.start()
        upload.join(timeout=1.0)
        assert upload.is_alive(), "the second upload did not wait for the demonstrator's lock"
        forward = create_task(
            first, first.get_one(Demonstrator, dem["id"]), name="forward", mdp_id=mdp_id, metadata=None
        )
        first.commit()  # releases the lock
    upload.join(timeout=30)
    out = created(responses[0])
    joined = {t["label"]: (t["task_id"], t["created"]) for t in out["tasks"]}
    assert joined["forward"] == (forward.id, False)
    listed = client.get(f"/v1/demonstrators/{dem['id']}/tasks", headers=auth).json()["data"]
    assert [t["id"] for t in listed if t["name"] == "forward"] == [forward.id]


def test_csv_and_json_store_the_same_demonstrations(
    app: FastAPI, client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    mdp_id = velocity_grid(client, auth)
    by_json = created(post_json(client, auth, make_demonstrator(client, auth)["id"], rows, mdp_id=mdp_id))
    by_csv = created(
        post_csv(client, auth, make_demonstrator(client, auth)["id"], to_csv(rows), mdp_id=mdp_id)
    )
    assert by_csv["format"] == "csv"
    for key in ("segments", "n_samples", "dropped_samples", "dropped_segments", "settings"):
        assert by_json[key] == by_csv[key], key
    with app.state.sessionmaker() as session:
        for a, b in zip(by_json["tasks"], by_csv["tasks"], strict=True):
            assert (a["label"], a["n_steps"]) == (b["label"], b["n_steps"])
            ta, tb = load_trajectories(session, a["task_id"]), load_trajectories(session, b["task_id"])
            assert [t.states.tolist() for t in ta] == [t.states.tolist() for t in tb]


def test_grid_option_creates_the_velocity_grid_once(
    client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    grid = {"width": SIZE, "height": SIZE}
    first = created(post_json(client, auth, make_demonstrator(client, auth)["id"], rows, grid=grid))
    again = created(post_json(client, auth, make_demonstrator(client, auth)["id"], rows, grid=grid))
    assert first["mdp_created"] and not again["mdp_created"] and again["mdp_id"] == first["mdp_id"]
    mdp = client.get(f"/v1/mdps/{first['mdp_id']}", headers=auth).json()
    assert (mdp["n_states"], mdp["n_actions"], mdp["layout"]["channels"]) == (8 * SIZE * SIZE, 8, 8)


def corrupt(rows: Rows, k: int, **values: Any) -> Rows:
    """A copy of the first 300 rows with sample `k` changed."""
    out = [dict(r) for r in rows[:300]]
    out[k] |= values
    return out


BAD = [
    ("unsorted time", lambda rows: corrupt(rows, 17, t=rows[5]["t"]), "/samples/17/t", "strictly increase"),
    ("NaN", lambda rows: corrupt(rows, 9, x=float("nan")), "/samples/9/x", "finite"),
    ("off the plate", lambda rows: corrupt(rows, 4, y=0.5), "/samples/4/y", "outside the plate"),
    (
        "unknown instruction",
        lambda rows: corrupt(rows, 2, instruction="up"),
        "/samples/2/instruction",
        "unknown",
    ),
    ("empty", lambda rows: [], "/samples", "empty"),
]


@pytest.mark.parametrize(("make", "pointer", "words"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
@pytest.mark.parametrize("fmt", ["json", "csv"])
def test_a_bad_recording_is_422_naming_the_sample_and_stores_nothing(
    client: TestClient, auth: dict[str, str], rows: Rows, make: Any, pointer: str, words: str, fmt: str
) -> None:
    dem = make_demonstrator(client, auth)
    samples = make(rows)
    if fmt == "json":
        response = post_json(client, auth, dem["id"], samples, grid={"width": SIZE, "height": SIZE})
    else:
        response = post_csv(client, auth, dem["id"], to_csv(samples), grid='{"width": 20, "height": 20}')
    assert response.status_code == 422, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    errors = response.json()["errors"]
    assert any(e["pointer"] == pointer and words in e["message"] for e in errors), errors
    if fmt == "csv" and pointer != "/samples":
        line = int(pointer.split("/")[2]) + 2  # header is line 1
        assert any(f"CSV line {line}" in e["message"] for e in errors), errors
    assert tasks_of(client, auth, dem["id"]) == {}
    assert client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"] == []
    assert client.get("/v1/mdps", headers=auth).json()["data"] == []


def test_a_csv_cell_that_is_not_a_number_names_sample_and_line(
    client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    text = to_csv(rows[:50]).replace(f"{rows[6]['x']!r}", "left", 1)
    response = post_csv(
        client, auth, make_demonstrator(client, auth)["id"], text, grid='{"width": 20, "height": 20}'
    )
    assert response.status_code == 422, response.text
    assert response.json()["errors"][0]["pointer"] == "/samples/6/x"
    assert "CSV line 8" in response.json()["errors"][0]["message"]


def test_a_failure_after_the_first_task_rolls_back_the_whole_upload(
    client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    dem = make_demonstrator(client, auth)
    corridor = make_mdp(client, auth)["id"]
    clash = created(
        client.post(
            f"/v1/demonstrators/{dem['id']}/tasks", json={"name": "right", "mdp_id": corridor}, headers=auth
        )
    )
    response = post_json(client, auth, dem["id"], rows, grid={"width": SIZE, "height": SIZE})
    assert response.status_code == 409, response.text
    assert clash["id"] in response.json()["detail"]
    # The grid made for the upload is rolled back with it: named by its size and field, not by a dead id.
    assert response.json()["errors"] == [
        {
            "pointer": "/grid",
            "message": f"Task {clash['id']!r} ('right') of this demonstrator is on MDP {corridor!r}, not on a "
            f"{SIZE}×{SIZE} velocity grid",
        }
    ]
    assert list(tasks_of(client, auth, dem["id"])) == ["right"]  # "forward" was created, then rolled back
    assert client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"] == []
    assert [m["id"] for m in client.get("/v1/mdps", headers=auth).json()["data"]] == [corridor]


def test_the_mdp_must_be_a_velocity_grid_of_the_lab(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str], rows: Rows
) -> None:
    dem = make_demonstrator(client, auth)
    for mdp_id in (make_mdp(client, auth)["id"], velocity_grid(client, auth_b)):
        response = post_json(client, auth, dem["id"], rows[:300], mdp_id=mdp_id)
        assert response.status_code == 422 and response.json()["errors"][0]["pointer"] == "/mdp_id"
    neither = post_json(client, auth, dem["id"], rows[:300])
    assert neither.status_code == 422 and neither.json()["errors"][0]["pointer"] == "/mdp_id"


def test_a_recording_with_a_name_too_long_and_a_sample_off_the_plate_lists_both(
    client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    dem = make_demonstrator(client, auth)
    samples = corrupt(rows, 4, y=0.5)
    grid = {"width": SIZE, "height": SIZE}
    response = post_json(client, auth, dem["id"], samples, grid=grid, name="n" * 201)
    assert response.status_code == 422, response.text
    errors = response.json()["errors"]
    assert [e["pointer"] for e in errors] == ["/name", "/samples/4/y"]
    assert "outside the plate" in errors[1]["message"]
    assert client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"] == []
    assert client.get("/v1/mdps", headers=auth).json()["data"] == []


def test_a_recording_with_a_bad_segment_setting_and_an_unknown_mdp_lists_both(
    client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    """The segment settings the schema refuses are not used to cut; the MDP is still looked up."""
    dem = make_demonstrator(client, auth)
    response = post_json(
        client, auth, dem["id"], rows[:300], mdp_id="mdp_nope", segment={"min_prominence": "high"}
    )
    assert response.status_code == 422, response.text
    errors = response.json()["errors"]
    assert [e["pointer"] for e in errors] == ["/segment/min_prominence", "/mdp_id"]
    assert "no MDP with id 'mdp_nope'" in errors[1]["message"]


def test_samples_the_schema_refuses_are_not_judged_but_a_grid_over_the_limits_is(
    client: TestClient, auth: dict[str, str], rows: Rows
) -> None:
    dem = make_demonstrator(client, auth)
    samples = corrupt(rows, 3, t="zero")
    response = post_json(client, auth, dem["id"], samples, grid={"width": 100_000, "height": 100_000})
    assert response.status_code == 422, response.text
    errors = response.json()["errors"]
    assert [e["pointer"] for e in errors] == ["/samples/3/t", "/grid/width"]
    assert "METAIRL_MAX_STATE_ACTIONS" in errors[1]["message"]


def test_another_lab_gets_404(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str], rows: Rows
) -> None:
    dem = make_demonstrator(client, auth)
    response = post_json(client, auth_b, dem["id"], rows, grid={"width": SIZE, "height": SIZE})
    assert response.status_code == 404, response.text
    assert client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth_b).status_code == 404
    assert client.get("/v1/mdps", headers=auth_b).json()["data"] == []


def test_cutting_a_recording_never_imports_torch() -> None:
    code = (
        "import sys, numpy as np; import service.store.recordings as r; from service.domain.recordings import RecordingIn\n"
        "from service.files.recording_samples import json_samples\n"
        "t = np.arange(0, 8, 0.01); x = 0.15 * np.sin(np.pi * t / 2).clip(0) ** 2\n"
        "body = RecordingIn.model_validate({'bounds': {'x_min': -0.2, 'x_max': 0.2, 'y_min': -0.2, 'y_max': 0.2},"
        " 'samples': [{'t': a, 'x': b, 'y': 0.0} for a, b in zip(t.tolist(), x.tolist())]})\n"
        "s = json_samples(body)\n"
        "cut = r.demonstrations(r.Recording.build(t=s.t, x=s.x, y=s.y, bounds=body.bounds),"
        " discretise_settings=r.DiscretiseSettings(width=20, height=20), segment_settings=body.segment)\n"
        "print(sorted(cut.by_label), 'torch' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "['right'] False"
