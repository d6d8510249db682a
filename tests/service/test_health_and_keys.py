"""Probes, API-key authentication and the `metairl keys create` command."""

from __future__ import annotations

import os
import subprocess
import sys
from datetime import datetime, timedelta
from pathlib import Path

from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import create_engine, event, select, update
from sqlalchemy.orm import sessionmaker

from service.api.app import create_app
from service.api.auth import Caller, KeyCache
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.labs import ApiKey

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
    tmp_path: Path, empty_database_url: str
) -> None:
    """On a database of its own: another process writing to the session's shared SQLite file while this one
    holds pooled connections to it has been seen to leave later tests with ``disk I/O error``."""
    settings = Settings(data_dir=tmp_path / "var", database_url=empty_database_url)
    app = create_app(settings)
    env = os.environ | {
        "METAIRL_DATA_DIR": str(settings.data_dir),
        "METAIRL_DATABASE_URL": settings.resolved_database_url,
    }
    try:
        with TestClient(app) as client:
            done = subprocess.run(
                [sys.executable, "-m", "metairl_cli.main", "keys", "create", "--lab", "cli lab"],
                cwd=REPO,
                env=env,
                capture_output=True,
                text=True,
                timeout=60,
                check=True,
            )
            key = done.stdout.strip().splitlines()[-1]
            assert " " not in key
            assert (
                client.get("/v1/demonstrators", headers={"Authorization": f"Bearer {key}"}).status_code == 200
            )
    finally:
        app.state.engine.dispose()


def test_importing_the_app_does_not_import_torch() -> None:
    code = "import sys, service.api.app, service.store.loaders, service.store.keys; print('torch' in sys.modules)"
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "False"


def test_a_confirmed_key_is_cached_for_the_ttl_and_a_revoked_key_refused_after_it(
    app: FastAPI, client: TestClient, api_key: str
) -> None:
    now = [1000.0]
    app.state.key_cache = KeyCache(5.0, clock=lambda: now[0])
    statements: list[str] = []
    event.listen(app.state.engine, "before_cursor_execute", lambda *a: statements.append(a[2]))
    auth = {"Authorization": f"Bearer {api_key}"}
    assert client.get("/v1/mdps", headers=auth).status_code == 200
    assert any("api_keys" in s for s in statements)  # the key was looked up
    statements.clear()
    assert client.get("/v1/mdps", headers=auth).status_code == 200
    assert statements and not any("api_keys" in s for s in statements)  # the key lookup was skipped

    with app.state.sessionmaker() as session:
        session.execute(update(ApiKey).where(ApiKey.id == api_key.split("_")[1]).values(revoked_at=utcnow()))
        session.commit()
    now[0] += 4.9
    assert client.get("/v1/mdps", headers=auth).status_code == 200  # within the TTL
    now[0] += 0.2
    assert client.get("/v1/mdps", headers=auth).status_code == 401  # revoked, and asked again
    assert client.get("/v1/mdps", headers=auth).status_code == 401  # refusals are never cached


def test_the_key_cache_is_bounded_and_off_at_zero() -> None:
    caller = Caller(id="lab_1", name="one")
    off = KeyCache(0)
    off.put("k", caller)
    assert off.get("k") is None
    now = [0.0]
    small = KeyCache(10, max_entries=3, clock=lambda: now[0])
    for key in ("a", "b", "c", "d"):
        small.put(key, caller)
    assert [small.get(k) for k in "abcd"] == [None, caller, caller, caller]
    now[0] = 10.0
    assert small.get("d") is None


def test_a_lost_database_is_a_503_problem_to_retry(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    app.state.sessionmaker = sessionmaker(create_engine("postgresql+psycopg://nobody@127.0.0.1:1/none"))
    response = client.get("/v1/mdps", headers=auth)
    assert response.status_code == 503 and response.headers["Retry-After"] == "1"
    assert response.headers["content-type"].startswith("application/problem+json")
    assert response.json()["title"] == "Database unavailable"


def test_the_api_process_imports_only_what_it_serves(app: FastAPI, settings: Settings) -> None:
    """Building the app on a migrated database loads neither torch nor scipy, matplotlib, Alembic or Celery
    (comparisons, heatmaps, migrations and job submission import theirs when first used)."""
    heavy = ("torch", "scipy", "matplotlib", "alembic", "celery")
    code = (
        "import sys; from service.api.app import create_app; create_app()\n"
        f"print(sorted(m for m in {heavy!r} if m in sys.modules))"
    )
    env = os.environ | {
        "METAIRL_DATABASE_URL": settings.resolved_database_url,
        "METAIRL_DATA_DIR": str(settings.data_dir),
    }
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "[]", done.stderr


def test_a_request_with_a_key_records_its_use_and_the_next_one_after_a_minute_again(
    app: FastAPI, client: TestClient, api_key: str
) -> None:
    key_id = api_key.split("_")[1]

    def last_used() -> object:
        with app.state.sessionmaker() as session:
            return session.execute(select(ApiKey.last_used_at).where(ApiKey.id == key_id)).scalar_one()

    headers = {"Authorization": f"Bearer {api_key}"}
    assert client.get("/v1/mdps", headers=headers).status_code == 200
    first = last_used()
    assert first is not None
    with app.state.sessionmaker() as session:  # as if that use was two minutes ago
        session.execute(
            update(ApiKey).where(ApiKey.id == key_id).values(last_used_at=utcnow() - timedelta(minutes=2))
        )
        session.commit()
    assert client.get("/v1/mdps", headers=headers).status_code == 200
    again = last_used()
    assert isinstance(again, datetime) and isinstance(first, datetime) and again >= first
