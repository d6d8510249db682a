"""Probes, API-key authentication and the `metairl keys create` command."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, select

from service.models.labs import ApiKey
from service.settings import Settings

REPO = Path(__file__).resolve().parents[2]


def test_healthz_answers_without_a_key(client: TestClient) -> None:
    response = client.get("/healthz")
    assert response.status_code == 200
    assert response.json() == {"status": "ok"}


def test_readyz_is_200_with_the_database_and_503_without(app: FastAPI, client: TestClient) -> None:
    assert client.get("/readyz").status_code == 200
    app.state.engine = create_engine("postgresql+psycopg://nobody@127.0.0.1:1/none")
    response = client.get("/readyz")
    assert response.status_code == 503
    assert response.json()["status"] == "unavailable"


def test_v1_routes_need_a_bearer_key(client: TestClient) -> None:
    response = client.get("/v1/mdps")
    assert response.status_code == 401
    assert response.headers["content-type"].startswith("application/problem+json")
    assert response.headers["www-authenticate"] == "Bearer"


def test_unknown_and_tampered_keys_are_rejected(client: TestClient, api_key: str) -> None:
    tampered = api_key[:-2] + ("AA" if not api_key.endswith("AA") else "BB")
    for key in ("nonsense", "mirl_0123456789abcdef_secret", tampered):
        response = client.get("/v1/mdps", headers={"Authorization": f"Bearer {key}"})
        assert response.status_code == 401, key
    assert client.get("/v1/mdps", headers={"Authorization": f"Bearer {api_key}"}).status_code == 200


def test_keys_are_stored_hashed(app: FastAPI, api_key: str) -> None:
    secret = api_key.split("_", 2)[2]
    with app.state.sessionmaker() as session:
        stored = session.execute(
            select(ApiKey.secret_sha256).where(ApiKey.id == api_key.split("_")[1])
        ).scalar_one()
    assert secret not in stored
    assert len(stored) == 64


def test_keys_create_command_prints_a_working_key_on_its_last_line(
    settings: Settings, app: FastAPI, client: TestClient
) -> None:
    env = os.environ | {
        "METAIRL_DATA_DIR": str(settings.data_dir),
        "METAIRL_DATABASE_URL": settings.resolved_database_url,
    }
    done = subprocess.run(
        [sys.executable, "-m", "service.cli", "keys", "create", "--lab", "cli lab"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    key = done.stdout.strip().splitlines()[-1]
    assert " " not in key
    assert client.get("/v1/demonstrators", headers={"Authorization": f"Bearer {key}"}).status_code == 200


def test_importing_the_app_does_not_import_torch() -> None:
    code = "import sys, service.app, service.inputs, service.keys; print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"
