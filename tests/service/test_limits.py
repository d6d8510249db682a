"""Request size limits: 413 problem naming the configured limit, by Content-Length and by counted bytes."""

from __future__ import annotations

import secrets
from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings


@pytest.fixture
def small(settings: Settings) -> Iterator[tuple[TestClient, dict[str, str]]]:
    """A client of an app with a 1000-byte JSON limit and a 2000-byte upload limit, and lab headers."""
    app = create_app(settings.model_copy(update={"max_json_bytes": 1000, "max_upload_bytes": 2000}))
    with app.state.sessionmaker() as session:
        key = create_key(session, f"limits-{secrets.token_hex(4)}")
    with TestClient(app) as client:
        yield client, {"Authorization": f"Bearer {key}"}
    app.state.engine.dispose()


def test_json_over_the_limit_is_413_by_content_length(small: tuple[TestClient, dict[str, str]]) -> None:
    client, auth = small
    response = client.post(
        "/v1/demonstrators", json={"name": "p", "metadata": {"pad": "x" * 2000}}, headers=auth
    )
    assert response.status_code == 413
    assert response.headers["content-type"].startswith("application/problem+json")
    assert "1000 bytes" in response.json()["detail"]


def test_streamed_body_without_length_is_counted(small: tuple[TestClient, dict[str, str]]) -> None:
    client, auth = small

    def chunks() -> Iterator[bytes]:
        yield b'{"name": "p", "metadata": {"pad": "'
        for _ in range(20):
            yield b"x" * 100
        yield b'"}}'

    response = client.post(
        "/v1/demonstrators",
        content=chunks(),
        headers=auth | {"Content-Type": "application/json", "Idempotency-Key": "s"},
    )
    assert response.status_code == 413
    assert "1000 bytes" in response.json()["detail"]
    assert client.get("/v1/demonstrators", headers=auth).json()["data"] == []


def test_uploads_have_their_own_limit(small: tuple[TestClient, dict[str, str]]) -> None:
    client, auth = small
    response = client.post(
        "/v1/mdps", files={"file": ("mdp.npz", b"x" * 3000)}, data={"name": "m", "gamma": "0.9"}, headers=auth
    )
    assert response.status_code == 413
    assert "2000 bytes" in response.json()["detail"]
    small_upload = client.post(
        "/v1/mdps", files={"file": ("mdp.npz", b"x" * 1500)}, data={"name": "m", "gamma": "0.9"}, headers=auth
    )
    assert small_upload.status_code == 422
