"""docker-compose.yml's production shape run natively (no Docker here): its api and worker commands and
environment, as written, on the machine's PostgreSQL and Redis, serve a lab's job through its health checks."""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from metairl_client import Client
from service.jobs.broker import delete_queue
from service.settings import Settings
from tests.jobs.conftest import REPO, _drop_postgres_database, _postgres_database
from tests.served import free_port

pytestmark = [pytest.mark.worker, pytest.mark.slow, pytest.mark.redis, pytest.mark.postgres]

COMPOSE = yaml.safe_load((REPO / "docker-compose.yml").read_text())
BIN = str(Path(sys.executable).parent)
"""Where this environment's console scripts (uvicorn, metairl, celery) are: the image's PATH has them."""


def native(value: str, *, database_url: str) -> str:
    """A compose environment value for this machine: the postgres and redis services are on 127.0.0.1."""
    if value.startswith("postgresql"):
        return database_url
    return value.replace("redis://redis:", "redis://127.0.0.1:")


def environment(service: str, *, database_url: str, data_dir: Path, queue: str) -> dict[str, str]:
    """The service's compose environment on this machine, with a test queue and data folder of its own."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
    env |= {
        k: native(str(v), database_url=database_url)
        for k, v in COMPOSE["services"][service]["environment"].items()
    }
    env |= {"METAIRL_DATA_DIR": str(data_dir), "METAIRL_QUEUE_NAME": queue, "HOSTNAME": socket.gethostname()}
    env["PATH"] = f"{BIN}{os.pathsep}{env.get('PATH', '')}"
    return env


def on_port(command: list[str], port: int) -> list[str]:
    """A compose command or health check with the container's port 8000 replaced by ``port``."""
    return [re.sub(r"\b8000\b", str(port), part) for part in command]


def health_check(service: str, env: dict[str, str], port: int) -> subprocess.CompletedProcess[bytes]:
    """Run the service's compose health check (``CMD`` or ``CMD-SHELL``) as Docker would."""
    kind, *command = on_port(COMPOSE["services"][service]["healthcheck"]["test"], port)
    argv = ["sh", "-c", command[0].replace("$$", "$")] if kind == "CMD-SHELL" else command
    return subprocess.run(argv, cwd=REPO, env=env, capture_output=True, timeout=60)


@contextlib.contextmanager
def started(command: list[str], env: dict[str, str], log: Path) -> Iterator[subprocess.Popen[bytes]]:
    """A compose service's command in its own process group, killed (with its children) on exit."""
    with log.open("wb") as sink:
        process = subprocess.Popen(
            command, cwd=REPO, env=env, stdout=sink, stderr=subprocess.STDOUT, start_new_session=True
        )
    try:
        yield process
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def until_healthy(
    service: str, env: dict[str, str], port: int, process: subprocess.Popen[bytes], log: Path
) -> None:
    """Wait, as compose's ``condition: service_healthy`` does, for the service's health check to pass."""
    deadline = time.monotonic() + 90
    while health_check(service, env, port).returncode != 0:
        assert process.poll() is None, f"{service} exited:\n{log.read_text()}"
        assert time.monotonic() < deadline, f"{service} not healthy after 90 s:\n{log.read_text()}"
        time.sleep(0.5)


def ring_world(lab: Client) -> tuple[str, list[str]]:
    """A demonstrator with two tasks on a 6×6 grid, each shown walking to its own corner."""
    mdp = lab.create_mdp(
        {"kind": "grid", "name": "compose", "width": 6, "height": 6, "moves": 4, "gamma": 0.9}
    )
    demonstrator = lab.create_demonstrator(name="compose")
    tasks = []
    for goal_x in (0, 5):
        task = lab.create_task(demonstrator, name=f"to x={goal_x}", mdp_id=mdp)
        actions = [0 if goal_x else 2] * 5  # the 4-move grid's actions: right, forward, left, backward
        start = 5 - goal_x
        lab.add_demonstrations(
            task,
            [
                {
                    "states": [y * 6 + start + (step if goal_x else -step) for step in range(6)],
                    "actions": actions,
                }
                for y in range(3)
            ],
        )
        tasks.append(task)
    return demonstrator, tasks


@pytest.fixture
def database_url() -> Iterator[str]:
    """A fresh PostgreSQL database, dropped afterwards."""
    name, url = _postgres_database()
    try:
        yield url
    finally:
        _drop_postgres_database(name)


def test_compose_api_and_worker_commands_serve_a_job_and_pass_their_health_checks(
    tmp_path: Path, database_url: str
) -> None:
    services: dict[str, Any] = COMPOSE["services"]
    port, queue = free_port(), f"metairl-compose-{secrets.token_hex(4)}"
    envs = {
        name: environment(name, database_url=database_url, data_dir=tmp_path / "data", queue=queue)
        for name in ("api", "worker")
    }
    try:
        with started(on_port(services["api"]["command"], port), envs["api"], tmp_path / "api.log") as api:
            until_healthy("api", envs["api"], port, api, tmp_path / "api.log")
            keys = subprocess.run(
                ["metairl", "keys", "create", "--lab", "compose"],
                cwd=REPO,
                env=envs["api"],
                capture_output=True,
                text=True,
                timeout=60,
                check=True,
            )
            key = keys.stdout.strip().splitlines()[-1]
            with started(services["worker"]["command"], envs["worker"], tmp_path / "worker.log") as worker:
                until_healthy("worker", envs["worker"], port, worker, tmp_path / "worker.log")
                with Client.connect(url=f"http://127.0.0.1:{port}", api_key=key) as lab:
                    demonstrator, tasks = ring_world(lab)
                    job = lab.submit_job(demonstrator, config={"max_steps": 30, "hidden": [8]}).id
                    done = lab.wait(job, timeout_s=120)
                    assert done.status == "succeeded", done
                    baseline, per_task = lab.rewards(job)
                    assert baseline.shape == (36,) and np.isfinite(baseline).all()
                    assert set(per_task) == set(tasks)
    finally:
        delete_queue(Settings(broker_url=envs["worker"]["METAIRL_BROKER_URL"], queue_name=queue))
