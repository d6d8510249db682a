"""The per-request memory budget (``METAIRL_API_MAX_REQUEST_MEMORY_MB``): every upload kind is estimated
before it is built and refused with a 422 naming the setting when over it (a JSON body too large to parse
within it: a 413 naming the largest that fits); memory is handed back after a request that grew the process."""

from __future__ import annotations

import io
import json
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from service.api import memory
from service.api.app import create_app
from service.api.bodies import JSON_EXPANSION
from service.settings import Settings
from tests.conftest import _new_key
from tests.service.helpers import PLATE, make_demonstrator, make_task

BUDGET_MB = 16
SETTING = "METAIRL_API_MAX_REQUEST_MEMORY_MB"


@pytest.fixture
def small(settings: Settings) -> Iterator[tuple[FastAPI, TestClient, dict[str, str]]]:
    """The app with a 16 MiB per-request budget, its client and a lab's headers."""
    app = create_app(settings.model_copy(update={"api_max_request_memory_mb": BUDGET_MB}))
    with TestClient(app) as client:
        yield app, client, {"Authorization": f"Bearer {_new_key(app, 'lab-budget')}"}
    app.state.engine.dispose()


def refused(response: Any) -> str:
    """The message of a 422 that names the memory budget (a request that describes more than it holds)."""
    assert response.status_code == 422, response.text[:300]
    message: str = response.json()["errors"][0]["message"]
    assert SETTING in message, message
    return message


def test_a_json_body_whose_parsed_form_exceeds_the_budget_is_413_naming_the_largest_that_fits(
    small: tuple[FastAPI, TestClient, dict[str, str]],
) -> None:
    _, client, auth = small
    task = make_task(client, auth)
    trajectories = [{"states": [0, 1, 2] * 100, "actions": [1, 1, 0] * 100} for _ in range(1200)]
    body = json.dumps({"trajectories": trajectories})
    assert len(body) > 2 * 2**20
    url = f"/v1/tasks/{task['id']}/demonstrations"
    response = client.post(url, content=body, headers=auth | {"Content-Type": "application/json"})
    assert response.status_code == 413, response.text[:300]
    assert response.headers["content-type"].startswith("application/problem+json")
    largest = BUDGET_MB / JSON_EXPANSION  # MiB of JSON the budget holds
    assert f"JSON bodies up to {largest:,.1f} MiB" in response.json()["detail"]
    assert SETTING in response.json()["detail"]


def test_a_csv_with_more_rows_than_the_budget_holds_is_422(
    small: tuple[FastAPI, TestClient, dict[str, str]],
) -> None:
    _, client, auth = small
    task = make_task(client, auth)
    rows = "".join(f"t{k // 100},{k % 100},1,1\n" for k in range(120_000))
    csv = ("trajectory,step,state,action\n" + rows).encode()
    response = client.post(
        f"/v1/tasks/{task['id']}/demonstrations", files={"file": ("d.csv", csv)}, headers=auth
    )
    assert response.json()["errors"][0]["pointer"] == "/file" and "CSV rows" in refused(response)
    demonstrator = make_demonstrator(client, auth)
    samples = ("t,x,y\n" + "".join(f"{k / 100},0,0\n" for k in range(60_000))).encode()
    response = client.post(
        f"/v1/demonstrators/{demonstrator['id']}/recordings",
        files={"file": ("cop.csv", samples)},
        data={"bounds": json.dumps(PLATE), "grid": json.dumps({"width": 4, "height": 4})},
        headers=auth,
    )
    refused(response)


def test_a_grid_is_estimated_before_it_is_built(small: tuple[FastAPI, TestClient, dict[str, str]]) -> None:
    _, client, auth = small
    body = {"kind": "grid", "name": "big", "width": 300, "height": 300, "gamma": 0.9}
    assert "building the 300×300 grid" in refused(client.post("/v1/mdps", json=body, headers=auth))
    too_many = {
        "kind": "grid",
        "name": "huge",
        "width": 100_000,
        "height": 100_000,
        "velocity": True,
        "gamma": 0.9,
    }
    response = client.post("/v1/mdps", json=too_many, headers=auth)
    assert response.status_code == 422 and "METAIRL_MAX_STATE_ACTIONS" in response.text


def test_npz_members_are_weighed_from_their_headers(
    small: tuple[FastAPI, TestClient, dict[str, str]],
) -> None:
    _, client, auth = small
    buffer = io.BytesIO()
    np.savez_compressed(buffer, next_state=np.zeros((1000, 1000), dtype=np.int64))
    response = client.post(
        "/v1/mdps",
        files={"file": ("mdp.npz", buffer.getvalue())},
        data={"name": "m", "gamma": "0.9"},
        headers=auth,
    )
    assert response.json()["errors"][0]["pointer"] == "/file" and ".npz" in refused(response)


def test_memory_is_handed_back_after_a_request_that_grew_the_process(
    client: TestClient, auth: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    sizes = iter([100 * 2**20, 400 * 2**20, 100 * 2**20, 110 * 2**20])
    trims: list[int] = []
    monkeypatch.setattr(memory, "resident_bytes", lambda: next(sizes))
    monkeypatch.setattr(memory, "_malloc_trim", lambda: trims.append(1))
    client.post("/v1/demonstrators", json={"name": "grew"}, headers=auth)
    assert trims == [1]
    client.post("/v1/demonstrators", json={"name": "did not"}, headers=auth)
    assert trims == [1]
