"""Keyset pagination of lists: `limit`, `cursor`, `has_more`, `next_cursor`."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from tests.service.helpers import make_demonstrator


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
