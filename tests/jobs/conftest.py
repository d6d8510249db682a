"""Fixtures for the jobs tests: a whole stack per backend (database, broker, API client) and real workers.

Backends: ``embedded`` (SQLite file + Celery ``filesystem://`` broker, what ``metairl serve`` runs),
``redis_pg`` (the machine's PostgreSQL + Redis, what docker-compose runs) and ``rabbitmq_pg`` (PostgreSQL +
the machine's RabbitMQ). Workers are real processes
started with ``python -m metairl_cli.main worker`` (the ``metairl worker`` command) in their own process group,
and are always killed in teardown. Heartbeats, the reaper and the stale cutoff are shortened by settings.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import secrets
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import psycopg
import pytest
from fastapi.testclient import TestClient
from psycopg import sql

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.jobs.broker import delete_queue
from service.settings import Settings
from tests.conftest import POSTGRES_ADMIN

REPO = Path(__file__).resolve().parents[2]
BROKERS = {"redis_pg": "redis://127.0.0.1:6379/0", "rabbitmq_pg": "amqp://guest:guest@127.0.0.1:5672//"}
"""The machine's brokers, by the backend that uses them (each with PostgreSQL)."""
FAST = {
    "job_heartbeat_s": 0.3,
    "job_stale_after_s": 3.0,
    "reaper_interval_s": 1.0,
    "job_requeue_after_s": 2.0,
    "job_event_interval_s": 0.5,
    "job_max_attempts": 3,
}
"""Lifecycle timings short enough for a test suite (production defaults are seconds to minutes)."""


def settings_environment(settings: Settings) -> dict[str, str]:
    """The ``METAIRL_*`` environment that gives a child process exactly these settings."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
    for name, value in settings.model_dump(exclude_none=True).items():
        env[f"METAIRL_{name.upper()}"] = str(value)
    return env


@dataclass
class Workers:
    """Worker processes of one stack; each runs in its own session so its whole pool can be killed."""

    settings: Settings
    logs: Path
    running: list[subprocess.Popen[bytes]] = field(default_factory=list)

    def start(self, **overrides: object) -> subprocess.Popen[bytes]:
        """Start ``metairl worker`` (with these settings changed) and wait until Celery reports it ready."""
        log = self.logs / f"worker-{len(self.running)}-{secrets.token_hex(3)}.log"
        with open(log, "wb") as out:
            process = subprocess.Popen(
                [sys.executable, "-m", "metairl_cli.main", "worker", "--concurrency", "1"],
                cwd=REPO,
                env=settings_environment(self.settings.model_copy(update=overrides)),
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        self.running.append(process)
        deadline = time.monotonic() + 60
        while b" ready." not in log.read_bytes():
            assert process.poll() is None, f"worker exited: {log.read_text()}"
            assert time.monotonic() < deadline, f"worker not ready after 60 s: {log.read_text()}"
            time.sleep(0.1)
        return process

    def current(self) -> subprocess.Popen[bytes]:
        """A live worker, starting one if none runs."""
        alive = [p for p in self.running if p.poll() is None]
        return alive[-1] if alive else self.start()

    def kill(self, process: subprocess.Popen[bytes]) -> None:
        """SIGKILL the worker and its pool processes at once (a crash: nothing gets to clean up)."""
        with contextlib.suppress(ProcessLookupError):  # the group may already be gone
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=10)

    def kill_all(self) -> None:
        """Teardown: kill every worker this stack started."""
        for process in self.running:
            self.kill(process)


@dataclass
class Stack:
    """One backend: settings, an API client and a lab's auth headers, and its workers."""

    name: str
    settings: Settings
    client: TestClient
    auth: dict[str, str]
    workers: Workers


def _postgres_database() -> tuple[str, str]:
    """A fresh PostgreSQL database: (name, SQLAlchemy URL)."""
    name = f"metairl_jobs_{secrets.token_hex(5)}"
    with psycopg.connect(POSTGRES_ADMIN, autocommit=True) as admin:
        admin.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
    return name, f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"


def _drop_postgres_database(name: str) -> None:
    """Drop a test database even if connections remain."""
    with psycopg.connect(POSTGRES_ADMIN, autocommit=True) as admin:
        admin.execute(sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(name)))


@pytest.fixture(
    scope="module",
    params=[
        "embedded",
        pytest.param("redis_pg", marks=[pytest.mark.redis, pytest.mark.postgres]),
        pytest.param("rabbitmq_pg", marks=[pytest.mark.rabbitmq, pytest.mark.postgres]),
    ],
)
def stack(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stack]:
    """A migrated database, a broker and an API client for one backend; its workers die with it."""
    root = tmp_path_factory.mktemp(request.param)
    database: str | None = None
    options: dict[str, object] = {
        "data_dir": root / "var",
        "queue_name": f"metairl-test-{secrets.token_hex(4)}",
    }
    if request.param in BROKERS:
        database, url = _postgres_database()
        options |= {"database_url": url, "broker_url": BROKERS[request.param]}
    settings = Settings(**options, **FAST)  # type: ignore[arg-type]
    workers = Workers(settings, root)
    app = create_app(settings)
    node = (
        node_of_this_machine(tmp_path_factory) if request.param == "rabbitmq_pg" else contextlib.nullcontext()
    )
    with node:
        try:
            with TestClient(app) as client, app.state.sessionmaker() as session:
                auth = {"Authorization": f"Bearer {create_key(session, f'jobs-{secrets.token_hex(3)}')}"}
                yield Stack(request.param, settings, client, auth, workers)
        finally:
            workers.kill_all()
            app.state.engine.dispose()
            if database:
                _drop_postgres_database(database)
            delete_queue(settings)  # the test's queue is durable on a shared broker


@contextlib.contextmanager
def node_of_this_machine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Hold, across this run's test processes (pytest-xdist's), the Celery node name every worker on this machine
    has (``celery@HOST``): on RabbitMQ a worker holds its node's exclusive queue ``celery@HOST.celery.pidbox``,
    so another process's worker would die at start (RESOURCE_LOCKED) while one runs."""
    with open(tmp_path_factory.getbasetemp().parent / "rabbitmq-node.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


@pytest.fixture
def worker(stack: Stack) -> subprocess.Popen[bytes]:
    """A live worker of the stack (started once per module and after a test killed it)."""
    return stack.workers.current()
