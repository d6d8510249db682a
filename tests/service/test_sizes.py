"""Size limits: an `.npz` bomb is refused from its headers before it is read,
and MDP sizes and hidden layers over the `METAIRL_MAX_*` settings are 422s naming the setting, on upload and
on job submission."""

from __future__ import annotations

import io
import resource
import zipfile
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from service.api.app import create_app
from service.files.npz import npz_headers
from service.settings import Settings
from tests.service.helpers import add_demonstrations, created, make_demonstrator, make_task


def npz(**arrays: np.ndarray) -> bytes:
    """A compressed `.npz` of `arrays`."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def upload(client: TestClient, auth: dict[str, str], data: bytes) -> Any:
    """POST an `.npz` MDP upload."""
    return client.post(
        "/v1/mdps", files={"file": ("mdp.npz", data)}, data={"name": "m", "gamma": "0.9"}, headers=auth
    )


def test_an_npz_bomb_is_refused_from_its_header_without_reading_it(
    client: TestClient, auth: dict[str, str]
) -> None:
    # A header declaring 2 GB of float32 and 512 MB of zeros behind it, in a small file; written in chunks
    # so the test itself never holds the array.
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f4", "fortran_order": False, "shape": (5_000_000, 100)}
    )
    buffer = io.BytesIO()
    with (
        zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive,
        archive.open("features.npy", "w", force_zip64=True) as member,
    ):
        member.write(header.getvalue())
        chunk = bytes(64 * 1024 * 1024)
        for _ in range(8):
            member.write(chunk)
    data = buffer.getvalue()
    assert len(data) < 2_000_000
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    response = upload(client, auth, data)
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    assert response.status_code == 422, response.text
    message = response.json()["errors"][0]["message"]
    assert "'features'" in message and "METAIRL_MAX_ARRAY_ELEMENTS" in message
    assert grown_mb < 200, grown_mb


def test_npz_headers_read_shapes_only(settings: Settings) -> None:
    data = npz(next_state=np.zeros((3, 2), np.int32), features=np.ones((3, 4), np.float32))
    headers = npz_headers(io.BytesIO(data), pointer="/file", settings=settings)
    assert {k: v[0] for k, v in headers.items()} == {"next_state": (3, 2), "features": (3, 4)}
    with pytest.raises(Exception, match=r"Python objects|readable"):
        npz_headers(io.BytesIO(npz(x=np.array([{}], dtype=object))), pointer="/file", settings=settings)


@pytest.fixture
def small_app(settings: Settings) -> Iterator[FastAPI]:
    """The app with small limits: 100 state-actions, 8 features, 128 hidden units, 1,000 elements per array."""
    limited = settings.model_copy(
        update={
            "max_state_actions": 100,
            "max_features": 8,
            "max_hidden_units": 128,
            "max_array_elements": 1000,
        }
    )
    application = create_app(limited)
    yield application
    application.state.engine.dispose()


def test_mdps_over_the_limits_are_422_naming_the_setting(
    app: FastAPI, small_app: FastAPI, auth: dict[str, str]
) -> None:
    with TestClient(small_app) as client:
        big = np.arange(60, dtype=np.int32).reshape(30, 2) % 30
        wide = np.zeros((30, 9), np.float32)
        for data, setting in (
            (npz(next_state=np.arange(10**6, dtype=np.int32).reshape(-1, 1)), "METAIRL_MAX_ARRAY_ELEMENTS"),
            (npz(next_state=np.concatenate([big, big])), "METAIRL_MAX_STATE_ACTIONS"),
            (npz(next_state=big[:, :1], features=wide), "METAIRL_MAX_FEATURES"),
        ):
            response = upload(client, auth, data)
            assert response.status_code == 422, response.text
            assert setting in response.json()["detail"] and response.json()["errors"][0]["pointer"] == "/file"
        grid = {"kind": "grid", "name": "g", "width": 10, "height": 10, "moves": 4, "gamma": 0.9}
        response = client.post("/v1/mdps", json=grid, headers=auth)
        assert response.status_code == 422 and "METAIRL_MAX_STATE_ACTIONS" in response.json()["detail"]
        assert client.post("/v1/mdps", json=grid | {"width": 5, "height": 5}, headers=auth).status_code == 201


def test_jobs_over_the_limits_are_422_naming_the_setting(
    client: TestClient, small_app: FastAPI, auth: dict[str, str]
) -> None:
    big = {"kind": "grid", "name": "g", "width": 10, "height": 10, "moves": 4, "gamma": 0.9}
    mdp = created(client.post("/v1/mdps", json=big, headers=auth))  # within the app's default limits
    task = make_task(client, auth, mdp_id=mdp["id"])
    add_demonstrations(client, auth, task["id"], [{"states": [0, 1], "actions": [0]}])
    body = {"demonstrator_id": task["demonstrator_id"]}
    with TestClient(small_app) as limited:  # the same database, with the limits lowered since
        response = limited.post("/v1/jobs", json=body, headers=auth)
        assert response.status_code == 422, response.text
        assert "METAIRL_MAX_STATE_ACTIONS" in response.json()["detail"]
        response = limited.post("/v1/jobs", json=body | {"config": {"hidden": [32, 100_000]}}, headers=auth)
        assert response.status_code == 422
        error = response.json()["errors"][0]
        assert error["pointer"] == "/config/hidden/1" and "METAIRL_MAX_HIDDEN_UNITS" in error["message"]
    assert client.get("/v1/jobs", headers=auth).json()["data"] == []


def test_a_job_on_an_mdp_over_the_limits_hears_of_its_bad_settings_in_the_same_answer(
    client: TestClient, small_app: FastAPI, auth: dict[str, str]
) -> None:
    big = {"kind": "grid", "name": "g", "width": 10, "height": 10, "moves": 4, "gamma": 0.9}
    task = make_task(client, auth, mdp_id=created(client.post("/v1/mdps", json=big, headers=auth))["id"])
    add_demonstrations(client, auth, task["id"], [{"states": [0, 1], "actions": [0]}])
    body = {"demonstrator_id": task["demonstrator_id"], "config": {"learning_rate": "fast"}}
    with TestClient(small_app) as limited:
        response = limited.post("/v1/jobs", json=body, headers=auth)
    assert response.status_code == 422, response.text
    errors = response.json()["errors"]
    assert [e["pointer"] for e in errors] == ["/config/learning_rate", "/demonstrator_id"]
    assert "METAIRL_MAX_STATE_ACTIONS" in errors[1]["message"]


def test_a_recording_that_would_create_a_grid_over_the_limits_is_422_at_the_grid_and_stores_nothing(
    small_app: FastAPI, auth: dict[str, str]
) -> None:
    samples = [{"t": 0.01 * k, "x": 0.0, "y": 0.0} for k in range(10)]
    bounds = {"x_min": -0.2, "x_max": 0.2, "y_min": -0.2, "y_max": 0.2}
    with TestClient(small_app) as client:
        dem = make_demonstrator(client, auth)
        response = client.post(
            f"/v1/demonstrators/{dem['id']}/recordings",
            json={"bounds": bounds, "samples": samples, "grid": {"width": 30, "height": 20}},
            headers=auth,
        )
        assert response.status_code == 422, response.text
        (error,) = response.json()["errors"]
        assert error["pointer"] == "/grid/width" and "METAIRL_MAX_STATE_ACTIONS" in error["message"]
        assert response.json()["detail"].startswith(
            "The recording is invalid. /grid/width: the 30×20 grid has 4,800 states"
        )
        assert client.get("/v1/mdps", headers=auth).json()["data"] == []
        assert client.get(f"/v1/demonstrators/{dem['id']}/recordings", headers=auth).json()["data"] == []


def test_a_grid_over_the_limits_is_422_at_its_larger_side(small_app: FastAPI, auth: dict[str, str]) -> None:
    grid = {"kind": "grid", "name": "g", "width": 3, "height": 10**30, "moves": 4, "gamma": 0.9}
    with TestClient(small_app) as client:
        response = client.post("/v1/mdps", json=grid, headers=auth)
    assert response.status_code == 422, response.text
    assert response.json()["errors"][0]["pointer"] == "/height"
