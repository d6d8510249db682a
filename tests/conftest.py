"""Shared fixtures: a database per backend (SQLite file, and a fresh PostgreSQL database per session), and per
test fresh settings, app, client and API keys for two labs (A and B)."""

from __future__ import annotations

import contextlib
import secrets
from collections.abc import Iterator
from pathlib import Path

import psycopg
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient
from psycopg import sql

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings

POSTGRES_ADMIN = "postgresql://postgres@127.0.0.1:5432/postgres"
"""Where test databases are created and dropped (the machine's PostgreSQL, trust auth)."""


@contextlib.contextmanager
def fresh_database(backend: str, folder: Path) -> Iterator[str]:
    """The URL of a new, empty database: a SQLite file in `folder`, or a PostgreSQL database
    ``metairl_test_<random>`` that is dropped afterwards."""
    if backend == "sqlite":
        yield f"sqlite:///{folder / f'metairl-{secrets.token_hex(4)}.db'}"
        return
    name = f"metairl_test_{secrets.token_hex(6)}"
    with psycopg.connect(POSTGRES_ADMIN, autocommit=True) as admin:
        admin.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"
    finally:
        with psycopg.connect(POSTGRES_ADMIN, autocommit=True) as admin:
            admin.execute(sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(name)))


@pytest.fixture(scope="session", params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def backend(request: pytest.FixtureRequest) -> str:
    """The database backend the API tests run on (the whole suite runs once per backend)."""
    backend_name: str = request.param
    return backend_name


@pytest.fixture(scope="session")
def database_url(backend: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """One database per backend for the whole session (tests stay apart by using fresh labs)."""
    with fresh_database(backend, tmp_path_factory.mktemp(backend)) as url:
        yield url


@pytest.fixture
def empty_database_url(backend: str, tmp_path: Path) -> Iterator[str]:
    """A database of its own for this test, not yet migrated (for migration tests)."""
    with fresh_database(backend, tmp_path) as url:
        yield url


@pytest.fixture
def settings(tmp_path: Path, database_url: str) -> Settings:
    """Settings with a fresh data_dir and the session's database (tests stay apart by using fresh labs)."""
    return Settings(data_dir=tmp_path / "var", database_url=database_url)


@pytest.fixture
def app(settings: Settings) -> Iterator[FastAPI]:
    """The app, migrated, on the test's settings."""
    application = create_app(settings)
    yield application
    application.state.engine.dispose()


@pytest.fixture
def client(app: FastAPI) -> Iterator[TestClient]:
    """An HTTP client for the app (runs its lifespan)."""
    with TestClient(app) as test_client:
        yield test_client


def _new_key(app: FastAPI, prefix: str) -> str:
    """A key of a brand-new lab named `<prefix>-<random>`."""
    with app.state.sessionmaker() as session:
        return create_key(session, f"{prefix}-{secrets.token_hex(4)}")


@pytest.fixture
def api_key(app: FastAPI) -> str:
    """An API key of lab A (a new lab for every test)."""
    return _new_key(app, "lab-a")


@pytest.fixture
def api_key_b(app: FastAPI) -> str:
    """An API key of lab B, a second lab that must never see lab A's resources."""
    return _new_key(app, "lab-b")


@pytest.fixture
def auth(api_key: str) -> dict[str, str]:
    """Authorization headers of lab A."""
    return {"Authorization": f"Bearer {api_key}"}


@pytest.fixture
def auth_b(api_key_b: str) -> dict[str, str]:
    """Authorization headers of lab B."""
    return {"Authorization": f"Bearer {api_key_b}"}
