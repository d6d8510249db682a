"""``metairl serve``: the whole service on one machine — API (uvicorn) and one worker as child processes.

On the embedded defaults (SQLite file and Celery's ``filesystem://`` broker, both under
``METAIRL_DATA_DIR``) nothing else needs to run. Migrates, finds or creates the API key of the ``local``
lab, prints the URL, the docs URL and the key, and stops both children cleanly on SIGTERM or Ctrl-C.

The database keeps only a hash of each key, so the ``local`` key is kept in ``METAIRL_DATA_DIR/local-api-key``
(readable by its owner only): later starts print that key again while it is valid, and mint (and keep) a new
one only when the file is missing or its key was revoked.
"""

from __future__ import annotations

import errno
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Iterable, Mapping
from pathlib import Path

from sqlalchemy.orm import Session

from metairl_cli.keys import create_key
from service.jobs.broker import broker_url
from service.settings import Settings, get_settings
from service.store.db import NewerSchema, make_engine, migrate
from service.store.keys import key_is_valid

LOCAL_LAB = "local"
LOCAL_KEY_FILE = "local-api-key"
"""The file in the data folder that keeps the ``local`` lab's key between starts (mode 0600)."""
STARTUP_TIMEOUT_S = 60.0
WORKER_MAX_BACKOFF_S = 30.0
"""The longest wait before restarting a worker that keeps dying."""
WORKER_STABLE_S = 60.0
"""A worker that ran this long before dying is restarted after 1 s again (the backoff starts over)."""
SHUTDOWN_GRACE_S = 15.0
"""How long children get to stop after SIGTERM (a running job is re-run later by the reaper) before SIGKILL."""
ROOT_WARNING = "You're running the worker with superuser privileges"
"""The start of the SecurityWarning Celery's worker gives as root (`celery.platforms.check_privileges`)."""


def default_api_workers() -> int:
    """As many API processes as this process may use cores (its CPU affinity), at least one."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def api_command(python: str, *, host: str, port: int, workers: int, access_log: bool = False) -> list[str]:
    """uvicorn serving the app with `workers` processes on uvloop and httptools, without its access log
    unless ``access_log`` (a dashboard left open logs a line per poll: 1,155 in 12 minutes), and without its
    INFO lines on starting and stopping (`serve` says where it runs; uvicorn's level also gates its access
    log, so that keeps INFO).

    uvloop sets ``TCP_NODELAY`` on every connection; without it uvicorn's multi-process mode leaves Nagle's
    algorithm on, and each reused keep-alive connection stalls ~40 ms per response on delayed ACKs.
    """
    return [
        python, "-m", "uvicorn", "--factory", "service.api.app:create_app",
        "--host", host, "--port", str(port), "--workers", str(workers),
        "--loop", "uvloop", "--http", "httptools",
        "--access-log" if access_log else "--no-access-log",
        "--log-level", "info" if access_log else "warning",
    ]  # fmt: skip


def worker_command(python: str) -> list[str]:
    """One worker running one job at a time, quiet (`worker.main.run_worker`: no banner, warnings and errors
    only), and without Celery's warning against running as root.

    That warning is Celery's general advice (its ``--uid``, which `serve` has no use for); the danger it guards
    against, a root worker unpickling what the broker holds, does not arise: the worker accepts JSON only,
    and were pickle ever accepted Celery would refuse to start as root with a SecurityError, which no
    warning filter hides. ``C_FORCE_ROOT`` would not silence it: it only lets a root worker accept pickle."""
    return [
        python, "-W", f"ignore:{ROOT_WARNING}", "-m", "metairl_cli.main", "worker", "--concurrency", "1", "--quiet",
    ]  # fmt: skip


def serve(*, host: str, port: int, workers: int | None = None, access_log: bool = False) -> int:
    """Run API (`workers` processes, default one per core) and one worker until SIGTERM/SIGINT (exit 0) or
    until the API dies (exit 1); a worker that dies is restarted with backoff while the API stays up; exit 2
    at once, before anything is printed or created, if the port cannot be listened on, and exit 1 on a
    database that newer code migrated. The URL and the key are printed last, once the API answers and the
    worker said it is ready."""
    problem = port_problem(host, port)
    if problem is not None:
        print(f"metairl: {problem}", file=sys.stderr, flush=True)
        return 2
    settings = get_settings()
    env = child_environment(settings)
    engine = make_engine(settings)
    try:
        migrate(engine)
        with Session(engine) as session:
            key = local_key(session, settings.data_dir)
    except NewerSchema as exc:
        print(f"metairl: {exc}", file=sys.stderr, flush=True)
        return 1
    finally:
        engine.dispose()

    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    python = sys.executable
    # glibc gives each of the API's 40 request threads its own malloc arena (~25 MB more per process under
    # load); two arenas keep an API process near 125 MB. The worker (torch) keeps glibc's default.
    api_env = {"MALLOC_ARENA_MAX": "2", **env}
    worker_argv = worker_command(python)
    api_argv = api_command(
        python, host=host, port=port, workers=workers or default_api_workers(), access_log=access_log
    )
    worker, worker_ready = spawn_relayed(worker_argv, env)
    children = {"api": spawn(api_argv, api_env), "worker": worker}
    try:
        url = f"http://{host}:{port}"
        local = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::', '') else host}:{port}"
        if not wait_healthy(local, children, stop):
            return 0 if stop.is_set() else 1
        if not wait_ready(worker_ready, children, stop):
            return 0 if stop.is_set() else 1
        print(f"metairl is running at {url} (data in {settings.data_dir.resolve()})", flush=True)
        print(f"API docs: {url}/docs", flush=True)
        print(f"API key for lab {LOCAL_LAB!r} (send 'Authorization: Bearer <key>'):", flush=True)
        print(key, flush=True)
        restarts = WorkerRestarts()
        while not stop.wait(0.5):
            if children["api"].poll() is not None:
                print("metairl: the API exited unexpectedly; stopping", file=sys.stderr, flush=True)
                return 1
            code = children["worker"].poll()
            if code is not None:
                delay = restarts.next_delay(time.monotonic())
                print(
                    f"metairl: the worker exited with code {code}; restarting it in {delay:.0f} s "
                    "(the API stays up; a job it was running is re-run by the reaper)",
                    file=sys.stderr,
                    flush=True,
                )
                if stop.wait(delay):
                    break
                children["worker"], _ = spawn_relayed(worker_argv, env)
        return 0
    finally:
        shut_down(children.values())


class WorkerRestarts:
    """Backoff for restarting a worker that died: 1, 2, 4 … 30 s between restarts, back to 1 s once a worker
    has run WORKER_STABLE_S without dying."""

    def __init__(self) -> None:
        self.delay, self.last = 0.0, -WORKER_STABLE_S

    def next_delay(self, now: float) -> float:
        """Seconds to wait before the next restart, the worker having died at ``now``."""
        stable = now - self.last >= WORKER_STABLE_S
        self.delay = 1.0 if stable else min(2 * self.delay, WORKER_MAX_BACKOFF_S)
        self.last = now + self.delay
        return self.delay


def port_problem(host: str, port: int) -> str | None:
    """Why the API could not listen on ``host:port`` (one line naming the port), or None if it can.

    Binds a socket the way uvicorn will (``SO_REUSEADDR``, so a port left in TIME_WAIT counts as free) and
    closes it again; a server that grabs the port in between makes the API exit during start-up, which
    `serve` also reports before printing anything."""
    try:
        infos = socket.getaddrinfo(host or None, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (OSError, UnicodeError) as exc:
        return f"cannot listen on {host}:{port}: {exc}"
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(address)
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                return f"port {port} on {host} is already in use; stop what listens there or pass --port"
            return f"cannot listen on port {port} on {host}: {exc.strerror or exc}"
    return None


def local_key(session: Session, data_dir: Path) -> str:
    """The ``local`` lab's key kept in ``data_dir``, if it is still valid; else a new one, kept there."""
    path = data_dir / LOCAL_KEY_FILE
    try:
        kept = path.read_text().strip()
    except OSError:
        kept = ""
    if kept and key_is_valid(session, kept):
        return kept
    key = create_key(session, LOCAL_LAB)
    data_dir.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{LOCAL_KEY_FILE}.{os.getpid()}")
    fd = os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as handle:
        handle.write(key + "\n")
    os.replace(partial, path)
    return key


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


def spawn_relayed(argv: list[str], env: Mapping[str, str]) -> tuple[subprocess.Popen[bytes], threading.Event]:
    """Start a child like `spawn`, its output relayed line by line to our stderr by a thread, and an event set
    once a line says the Celery worker is ready (``celery@host ready.``; that line is not relayed: `serve`
    says it is running)."""
    child = subprocess.Popen(
        argv, env=dict(env), start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    ready = threading.Event()

    def relay() -> None:
        assert child.stdout is not None
        for raw in child.stdout:
            line = raw.decode(errors="replace")
            if line.rstrip().endswith(" ready."):
                ready.set()
                continue
            sys.stderr.write(line)
            sys.stderr.flush()

    threading.Thread(target=relay, name="worker-output", daemon=True).start()
    return child, ready


def wait_ready(
    ready: threading.Event, children: Mapping[str, subprocess.Popen[bytes]], stop: threading.Event
) -> bool:
    """Wait until the worker says it is ready; False if a child died or we were told to stop. After
    STARTUP_TIMEOUT_S it goes on (True) with a note: the API works, jobs wait in the queue."""
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while not ready.wait(0.2):
        if stop.is_set():
            return False
        if any(child.poll() is not None for child in children.values()):
            print(
                "metairl: a process exited during start-up; see its output above", file=sys.stderr, flush=True
            )
            return False
        if time.monotonic() > deadline:
            print(
                f"metairl: the worker has not said it is ready after {STARTUP_TIMEOUT_S:.0f} s; "
                "jobs wait in the queue until it is",
                file=sys.stderr,
                flush=True,
            )
            return True
    return True


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
