"""docker-compose.yml's production shape, read as compose would (no Docker here): what survives a reboot, where
the database password comes from, and when PostgreSQL counts as ready."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[1]


def services() -> dict[str, Any]:
    """The compose file's services."""
    return dict(yaml.safe_load((REPO / "docker-compose.yml").read_text())["services"])


def test_every_service_comes_back_after_a_reboot_not_only_the_api_and_worker() -> None:
    assert {name: s.get("restart") for name, s in services().items()} == dict.fromkeys(
        ("postgres", "redis", "api", "worker"), "unless-stopped"
    )


def test_the_database_password_is_one_variable_the_lab_sets_for_the_database_and_the_url() -> None:
    found = services()
    url = found["api"]["environment"]["METAIRL_DATABASE_URL"]
    assert found["worker"]["environment"]["METAIRL_DATABASE_URL"] == url
    password = re.fullmatch(r"postgresql\+psycopg://metairl:(.+)@postgres:5432/metairl", url)
    assert password is not None and password[1] == found["postgres"]["environment"]["POSTGRES_PASSWORD"]
    assert password[1].startswith("${POSTGRES_PASSWORD")


def test_postgres_is_ready_only_once_it_takes_network_connections() -> None:
    check = " ".join(services()["postgres"]["healthcheck"]["test"])
    assert "pg_isready -h 127.0.0.1" in check  # the first-start setup server listens on its socket only


def test_the_build_context_leaves_out_the_virtualenv_local_data_and_git() -> None:
    ignored = (REPO / ".dockerignore").read_text().split()
    assert {".git", ".venv", "var"} <= set(ignored)
