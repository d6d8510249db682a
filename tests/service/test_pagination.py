"""Keyset pagination of lists: `limit`, `cursor`, `has_more`, `next_cursor`."""

from __future__ import annotations

import base64
import json

import pytest
from fastapi.testclient import TestClient

from tests.service.helpers import make_demonstrator, queued_job


def test_pages_cover_every_item_once_newest_first(client: TestClient, auth: dict[str, str]) -> None:
    made = [make_demonstrator(client, auth, name=f"p{i}")["id"] for i in range(5)]
    seen: list[str] = []
    cursor = None
    pages = 0
    while True:
        params = {"limit": 2} | ({"cursor": cursor} if cursor else {})
        page = client.get("/v1/demonstrators", headers=auth, params=params).json()
        seen += [d["id"] for d in page["data"]]
        pages += 1
        if not page["has_more"]:
            assert page["next_cursor"] is None
            break
        cursor = page["next_cursor"]
    assert pages == 3
    assert seen == made[::-1]


def test_default_page_size_is_20(client: TestClient, auth: dict[str, str]) -> None:
    for i in range(21):
        make_demonstrator(client, auth, name=f"p{i}")
    page = client.get("/v1/demonstrators", headers=auth).json()
    assert len(page["data"]) == 20 and page["has_more"] is True


@pytest.mark.parametrize("params", [{"limit": 0}, {"limit": 101}, {"cursor": "not-a-cursor"}])
def test_bad_paging_parameters_are_422(client: TestClient, auth: dict[str, str], params: dict) -> None:
    response = client.get("/v1/demonstrators", headers=auth, params=params)
    assert response.status_code == 422
    assert response.json()["errors"][0]["parameter"] in ("limit", "cursor")


TAMPERED = [
    [1, 2],
    ["a", "b"],
    [{"at": "2026-01-05T10:00:00+00:00"}, ["x"]],
    [{"at": "2026-01-05T10:00:00+00:00"}, None],
    [{"at": "2026-01-05T10:00:00+00:00"}, 10**20],
    [{"at": 5}, "dem_x"],
]
"""Cursors of a list of resources made by hand: base64 JSON of two keys, with values of the wrong types."""
TAMPERED_EVENTS = [[10**20], [[1]], [None], [True], ["7"]]
"""The same for a job's event log, keyed by one integer."""


def hand_made(values: list) -> str:
    """A cursor as `encode_cursor` writes one, of any values."""
    return base64.urlsafe_b64encode(json.dumps(values).encode()).decode().rstrip("=")


@pytest.mark.parametrize(
    ("values", "event_values"), list(zip(TAMPERED, [*TAMPERED_EVENTS, [False]], strict=True))
)
def test_a_cursor_made_by_hand_is_422_naming_the_cursor(
    client: TestClient, auth: dict[str, str], values: list, event_values: list
) -> None:
    job = queued_job(client, auth)
    for url, cursor in (("/v1/jobs", hand_made(values)), (f"/v1/jobs/{job}/events", hand_made(event_values))):
        response = client.get(url, headers=auth, params={"cursor": cursor})
        assert response.status_code == 422, (url, response.text)
        assert response.json()["errors"][0]["parameter"] == "cursor"
