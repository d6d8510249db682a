"""The async read path of the hot routes (`GET /v1/jobs/{id}`, npy and json reward downloads): the key check and
the read in one statement on the lifespan's async engine, with the same answers as the sync routes.

Runs on SQLite (aiosqlite) and PostgreSQL (asyncpg), like every API test.
"""

from __future__ import annotations

import io
from datetime import timedelta
from typing import Any

import numpy as np
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import event, select, update
from sqlalchemy.ext.asyncio import AsyncEngine, create_async_engine
from sqlalchemy.pool import QueuePool

from service.api.async_db import ENGINE
from service.api.auth import KeyCache
from service.domain.jobs import JobOut
from service.store.db import async_url
from service.store.jobs import get_job
from service.store.models.base import utcnow
from service.store.models.jobs import Job
from service.store.models.labs import ApiKey
from tests.service.helpers import created, fitted_job, make_mdp

CORRIDOR = {"reach": [{"states": [0, 1, 2], "actions": [1, 1]}]}


@pytest.fixture
def job(app: FastAPI, client: TestClient, auth: dict[str, str]) -> dict[str, Any]:
    """A succeeded job of lab A on the 3-state corridor (baseline and one task reward), with its rewards."""
    rewards = np.arange(6, dtype=np.float32).reshape(2, 3) / 7
    fitted = fitted_job(
        app, client, auth, mdp=make_mdp(client, auth), demonstrations=CORRIDOR, rewards=rewards
    )
    return fitted | {"rewards": rewards}


def statements_of(engine: Any) -> list[str]:
    """The SQL `engine` (sync, or an async engine's `sync_engine`) runs from now on, appended as it runs."""
    seen: list[str] = []
    event.listen(engine, "before_cursor_execute", lambda *args: seen.append(args[2]))
    return seen


def key_id(api_key: str) -> str:
    """The public part of a key ``mirl_<id>_<secret>``."""
    return api_key.split("_")[1]


def set_key(app: FastAPI, api_key: str, **values: Any) -> None:
    """Write columns of the key's row, as another process (`metairl keys revoke`) would."""
    with app.state.sessionmaker() as session:
        session.execute(update(ApiKey).where(ApiKey.id == key_id(api_key)).values(**values))
        session.commit()


def test_a_job_is_read_in_one_statement_with_the_key_check_on_the_async_engine(
    app: FastAPI, client: TestClient, auth: dict[str, str], api_key: str, job: dict[str, Any]
) -> None:
    progress = {"step": 120, "max_steps": 500, "loss": 1.25, "irl_loss": 1.0, "sharing_loss": 0.25}
    with app.state.sessionmaker() as session:  # every kind of column: text, JSON, timestamps, floats
        session.execute(
            update(Job).where(Job.id == job["job_id"]).values(**progress, heldout_nll=None, elapsed_s=14.5)
        )
        session.commit()
    async_statements = statements_of(client.app_state[ENGINE].sync_engine)
    sync_statements = statements_of(app.state.engine)
    response = client.get(f"/v1/jobs/{job['job_id']}", headers=auth)
    assert response.status_code == 200, response.text
    assert len(async_statements) == 1 and "api_keys" in async_statements[0] and not sync_statements
    with app.state.sessionmaker() as session:
        lab_id = session.get_one(ApiKey, key_id(api_key)).lab_id
        expected = JobOut.of(get_job(session, job["job_id"], lab_id=lab_id))
    assert response.json() == expected.model_dump(mode="json")
    assert response.json()["status"] == "succeeded" and response.json()["progress"]["step"] == 120


def test_job_reads_refuse_keys_and_hide_other_labs_jobs_as_the_sync_routes_do(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str], api_key: str, job: dict[str, Any]
) -> None:
    path = f"/v1/jobs/{job['job_id']}"
    tampered = api_key[:-2] + ("AA" if not api_key.endswith("AA") else "BB")
    for headers in (
        {},
        {"Authorization": "Basic abc"},
        {"Authorization": "Bearer nonsense"},
        {"Authorization": "Bearer mirl_0123456789abcdef_secret"},
        {"Authorization": f"Bearer {tampered}"},
    ):
        fast = client.get(path, headers=headers)
        sync = client.get(f"{path}/events", headers=headers)  # a sync route behind the same key check
        assert (fast.status_code, fast.json(), fast.headers["www-authenticate"]) == (
            401,
            sync.json(),
            "Bearer",
        ), headers
        assert fast.headers["content-type"] == "application/problem+json"
    for headers, job_id in ((auth_b, job["job_id"]), (auth, "job_nope")):
        fast = client.get(f"/v1/jobs/{job_id}", headers=headers)
        sync = client.get(f"/v1/jobs/{job_id}/events", headers=headers)
        assert (fast.status_code, fast.json()) == (404, sync.json())
        assert fast.json()["detail"] == f"No job with id {job_id!r}."


def test_a_revoked_key_is_refused_at_once_even_with_a_key_cache(
    app: FastAPI, client: TestClient, auth: dict[str, str], api_key: str, job: dict[str, Any]
) -> None:
    app.state.key_cache = KeyCache(60.0)
    npy = f"/v1/rewards/{job['reward_ids'][1]}?format=npy"
    assert client.get(f"/v1/jobs/{job['job_id']}", headers=auth).status_code == 200
    assert client.get(npy, headers=auth).status_code == 200
    set_key(app, api_key, revoked_at=utcnow())
    assert client.get(f"/v1/jobs/{job['job_id']}", headers=auth).status_code == 401
    assert client.get(npy, headers=auth).status_code == 401
    assert client.get("/v1/mdps", headers=auth).status_code == 200  # the sync routes trust the cache's TTL


def test_a_job_read_records_the_keys_use_and_the_next_one_after_a_minute_again(
    app: FastAPI, client: TestClient, auth: dict[str, str], api_key: str, job: dict[str, Any]
) -> None:
    def last_used() -> Any:
        with app.state.sessionmaker() as session:
            return session.execute(
                select(ApiKey.last_used_at).where(ApiKey.id == key_id(api_key))
            ).scalar_one()

    set_key(app, api_key, last_used_at=None)
    async_statements = statements_of(client.app_state[ENGINE].sync_engine)
    assert client.get(f"/v1/jobs/{job['job_id']}", headers=auth).status_code == 200
    first = last_used()
    assert first is not None and len(async_statements) == 2  # the read, then the use
    async_statements.clear()
    assert client.get(f"/v1/jobs/{job['job_id']}", headers=auth).status_code == 200
    assert len(async_statements) == 1 and last_used() == first  # within the minute: no write
    set_key(app, api_key, last_used_at=utcnow() - timedelta(minutes=2))
    assert client.get(f"/v1/rewards/{job['reward_ids'][0]}?format=npy", headers=auth).status_code == 200
    assert last_used() >= first


def test_npy_serves_the_stored_bytes_with_their_etag_and_304_for_a_current_copy(
    client: TestClient, auth: dict[str, str], auth_b: dict[str, str], job: dict[str, Any]
) -> None:
    path = f"/v1/rewards/{job['reward_ids'][1]}"
    first = client.get(path, params={"format": "npy"}, headers=auth)
    assert first.status_code == 200 and first.headers["content-type"] == "application/octet-stream"
    np.testing.assert_array_equal(np.load(io.BytesIO(first.content)), job["rewards"][1])
    etag = first.headers["ETag"]
    assert first.headers["Cache-Control"] == "private, no-cache"
    again = client.get(path, params={"format": "npy"}, headers=auth | {"If-None-Match": etag})
    assert (again.status_code, again.content, again.headers["ETag"]) == (304, b"", etag)
    stale = client.get(path, params={"format": "npy"}, headers=auth | {"If-None-Match": '"old"'})
    assert (stale.status_code, stale.content) == (200, first.content)
    for headers in (auth_b, {}):
        refused = client.get(path, params={"format": "npy"}, headers=headers)
        assert refused.headers["content-type"] == "application/problem+json"
        assert refused.status_code == (404 if headers else 401)


def test_a_lost_database_is_a_503_problem_on_the_async_reads_too(
    client: TestClient, auth: dict[str, str], job: dict[str, Any]
) -> None:
    unreachable: AsyncEngine = create_async_engine("postgresql+asyncpg://nobody@127.0.0.1:1/none")
    client.app_state[ENGINE] = unreachable
    for path in (f"/v1/jobs/{job['job_id']}", f"/v1/rewards/{job['reward_ids'][1]}?format=npy"):
        response = client.get(path, headers=auth)
        assert response.status_code == 503 and response.headers["Retry-After"] == "1", response.text
        assert response.headers["content-type"] == "application/problem+json"
        assert response.json()["title"] == "Database unavailable"


def test_without_a_lifespan_each_request_reads_on_a_connection_of_its_own(
    app: FastAPI, auth: dict[str, str], job: dict[str, Any]
) -> None:
    """A test client not entered with ``with`` runs no lifespan and gives each request an event loop of its
    own (schemathesis and the docs' examples call the app so): the reads still answer."""
    bare = TestClient(app)
    for _ in range(2):
        assert created(bare.get(f"/v1/jobs/{job['job_id']}", headers=auth), 200)["id"] == job["job_id"]
        npy = bare.get(f"/v1/rewards/{job['reward_ids'][1]}?format=npy", headers=auth)
        np.testing.assert_array_equal(np.load(io.BytesIO(npy.content)), job["rewards"][1])


def test_the_lifespan_disposes_the_async_engine_at_shutdown(app: FastAPI, auth: dict[str, str]) -> None:
    with TestClient(app) as client:
        assert client.get("/v1/mdps", headers=auth).status_code == 200
        assert client.get("/v1/jobs/job_nope", headers=auth).status_code == 404
        pool = client.app_state[ENGINE].pool
        assert isinstance(pool, QueuePool)
        assert pool.checkedin() == 1  # the read's connection, kept for the next request
    assert pool.checkedin() == 0  # closed at shutdown


@pytest.mark.parametrize(
    ("configured", "expected"),
    [
        ("postgresql+psycopg://me:p%40ss@db:5433/metairl", "postgresql+asyncpg://me:p%40ss@db:5433/metairl"),
        ("postgresql://me@db/metairl?sslmode=require", "postgresql+asyncpg://me@db/metairl?ssl=require"),
        ("sqlite:///var/metairl.db", "sqlite+aiosqlite:///var/metairl.db"),
    ],
)
def test_the_async_url_is_the_configured_database_with_the_asyncio_driver(
    configured: str, expected: str
) -> None:
    assert async_url(configured).render_as_string(hide_password=False) == expected
