"""``metairl serve``: the whole service on one machine — API (uvicorn) and one worker as child processes.

On the embedded defaults (SQLite file and Celery's ``filesystem://`` broker, both under
``METAIRL_DATA_DIR``) nothing else needs to run. Migrates, creates an API key for the ``local`` lab,
prints the URL, the docs URL and the key, and stops both children cleanly on SIGTERM or Ctrl-C.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Iterable, Mapping

from sqlalchemy.orm import Session

from service.broker import broker_url
from service.db import make_engine, migrate
from service.keys import create_key
from service.settings import Settings, get_settings

LOCAL_LAB = "local"
STARTUP_TIMEOUT_S = 60.0
SHUTDOWN_GRACE_S = 15.0
"""How long children get to stop after SIGTERM (a running job is re-run later by the reaper) before SIGKILL."""


def serve(*, host: str, port: int) -> int:
    """Run API and worker until SIGTERM/SIGINT (exit 0) or until one of them dies (exit 1)."""
    settings = get_settings()
    env = child_environment(settings)
    engine = make_engine(settings)
    try:
        migrate(engine)
        with Session(engine) as session:
            key = create_key(session, LOCAL_LAB)
    finally:
        engine.dispose()

    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    python = sys.executable
    children = {
        "api": spawn(
            [
                python,
                "-m",
                "uvicorn",
                "--factory",
                "service.app:create_app",
                "--host",
                host,
                "--port",
                str(port),
            ],
            env,
        ),
        "worker": spawn([python, "-m", "service.cli", "worker", "--concurrency", "1"], env),
    }
    try:
        url = f"http://{host}:{port}"
        local = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::', '') else host}:{port}"
        if not wait_healthy(local, children, stop):
            return 0 if stop.is_set() else 1
        print(f"metairl is running at {url} (data in {settings.data_dir.resolve()})", flush=True)
        print(f"API docs: {url}/docs", flush=True)
        print(f"API key for lab {LOCAL_LAB!r} (send 'Authorization: Bearer <key>'):", flush=True)
        print(key, flush=True)
        while not stop.wait(0.5):
            dead = [name for name, child in children.items() if child.poll() is not None]
            if dead:
                print(
                    f"metairl: {', '.join(dead)} exited unexpectedly; stopping", file=sys.stderr, flush=True
                )
                return 1
        return 0
    finally:
        shut_down(children.values())


def child_environment(settings: Settings) -> dict[str, str]:
    """This process's environment with data dir, database and broker made explicit and absolute."""
    data_dir = settings.data_dir.resolve()
    data_dir.mkdir(parents=True, exist_ok=True)
    return {
        **os.environ,
        "METAIRL_DATA_DIR": str(data_dir),
        "METAIRL_DATABASE_URL": settings.model_copy(update={"data_dir": data_dir}).resolved_database_url,
        "METAIRL_BROKER_URL": broker_url(settings),
    }


def spawn(argv: list[str], env: Mapping[str, str]) -> subprocess.Popen[bytes]:
    """Start a child in its own session, so a terminal's Ctrl-C reaches only us and we stop it in order."""
    return subprocess.Popen(argv, env=dict(env), start_new_session=True)


def wait_healthy(url: str, children: Mapping[str, subprocess.Popen[bytes]], stop: threading.Event) -> bool:
    """Poll ``/healthz`` until it answers; False if a child died, we were told to stop, or time ran out."""
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while time.monotonic() < deadline and not stop.is_set():
        if any(child.poll() is not None for child in children.values()):
            print(
                "metairl: a process exited during start-up; see its output above", file=sys.stderr, flush=True
            )
            return False
        try:
            with urllib.request.urlopen(f"{url}/healthz", timeout=1) as response:
                if response.status == 200:
                    return True
        except OSError:
            pass
        stop.wait(0.2)
    if not stop.is_set():
        print(
            f"metairl: the API did not answer {url}/healthz within {STARTUP_TIMEOUT_S:.0f} s", file=sys.stderr
        )
    return False


def shut_down(children: Iterable[subprocess.Popen[bytes]]) -> None:
    """SIGTERM every child still running, wait up to SHUTDOWN_GRACE_S, then SIGKILL what is left."""
    alive = [c for c in children if c.poll() is None]
    for child in alive:
        child.terminate()
    deadline = time.monotonic() + SHUTDOWN_GRACE_S
    for child in alive:
        try:
            child.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)
            child.wait()
