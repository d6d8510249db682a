"""API load: requests per second and latency of the API under wrk, on loopback, for a bounded time.

Starts the API as it runs in production — ``uvicorn --factory service.api.app:create_app --workers N`` —
on a fresh PostgreSQL database with Redis as the broker (``postgres``), and on the embedded default, a
SQLite file with the ``filesystem://`` broker (``sqlite``). It seeds one lab and key, a 100×100 grid with
8 velocity directions (80,000 states) and a succeeded job whose baseline reward has 80,000 values (rows
written through the store layer, as the worker would), then runs ``wrk`` against

- ``GET /healthz`` (no database),
- ``GET /v1/jobs/{id}`` with a key (8 and 32 connections),
- ``GET /v1/rewards/{id}?format=npy`` (320 kB of float32),
- ``GET /v1/jobs/{id}/history`` with the longest loss curve a fit keeps (`HISTORY_STEPS` steps, as the
  worker stores it; about 17 MB of JSON per answer),

three times each, and prints a markdown table of the medians (req/s, p50, p99) with the load average
before each backend, the API worker RSS after the load, and the versions. Usage::

    python -m benchmarks.load [--backends postgres,sqlite] [--workers 2] [--duration 5]

Needs ``wrk`` (Debian: ``apt-get install wrk``), PostgreSQL at ``--postgres`` (trust auth; a database
``metairl_load_<random>`` is created and dropped) and Redis at ``--redis``. ``--app-dir`` serves the code of
another checkout (for a before/after comparison in one sitting) and ``--uvicorn-args`` adds options.
The rows, with their provenance and the served packages' versions, go to ``benchmarks/load_results.json``
(``--results``); the data folder is removed at the end.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import re
import secrets
import shlex
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

from benchmarks.provenance import provenance

ROOT = Path(__file__).resolve().parents[1]

N_STATES = 80_000
HISTORY_STEPS = 100_000
"""Steps of the seeded job's loss curve: the most a fit may run (`FitConfig.max_steps`' upper bound)."""
PACKAGES = ("uvicorn", "uvloop", "httptools", "fastapi", "starlette", "sqlalchemy", "psycopg")


@dataclass(frozen=True)
class Target:
    """One wrk run: a name for the table, the path, the connections, whether it sends the key."""

    name: str
    path: str
    connections: int
    keyed: bool = True


@dataclass(frozen=True)
class Result:
    """What wrk measured: requests per second, p50 and p99 latency (ms), non-2xx answers."""

    rps: float
    p50_ms: float
    p99_ms: float
    errors: int


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--backends", default="postgres,sqlite")
    parser.add_argument("--workers", type=int, default=2, help="uvicorn worker processes (default 2)")
    parser.add_argument("--duration", type=int, default=5, help="seconds per wrk run (default 5)")
    parser.add_argument("--runs", type=int, default=3, help="runs per row; the table shows medians")
    parser.add_argument("--postgres", default="postgresql://postgres@127.0.0.1:5432/postgres")
    parser.add_argument("--redis", default="redis://127.0.0.1:6379/15")
    parser.add_argument("--app-dir", type=Path, default=ROOT, help="the checkout whose API is served")
    parser.add_argument("--uvicorn-args", default="", help="extra uvicorn options, e.g. '--loop asyncio'")
    parser.add_argument(
        "--malloc-arena-max",
        type=int,
        default=2,
        help="MALLOC_ARENA_MAX of the API processes, as `metairl serve` sets it (0: leave glibc's default)",
    )
    parser.add_argument("--label", default="", help="a name for this run in the table's heading")
    parser.add_argument("--results", type=Path, default=ROOT / "benchmarks" / "load_results.json")
    args = parser.parse_args()
    if shutil.which("wrk") is None:
        sys.exit("load.py needs wrk (Debian: apt-get install wrk)")

    lines = [f"### {args.label or 'API load'}", ""]
    lines.append(
        f"`{versions(args.app_dir)}`; uvicorn --workers {args.workers} {args.uvicorn_args}".rstrip()
        + f"; MALLOC_ARENA_MAX={args.malloc_arena_max or 'unset'}"
        + f"; wrk -t2, {args.duration} s × {args.runs} runs, medians"
    )
    lines.append("")
    lines.append("| backend | request | conns | req/s | p50 ms | p99 ms | non-2xx | load avg (1 min) |")
    lines.append("| --- | --- | --- | --- | --- | --- | --- | --- |")
    rss_notes = []
    run = {**provenance(), "served": versions(args.app_dir)}
    rows: list[dict[str, Any]] = []
    rss: dict[str, dict[str, list[float]]] = {}
    for backend in args.backends.split(","):
        with database(backend, args.postgres) as (url, data_dir):
            key, job_id, reward_id = seed(url, data_dir)
            env = {
                **os.environ,
                "METAIRL_DATABASE_URL": url,
                "METAIRL_DATA_DIR": str(data_dir),
                "METAIRL_BROKER_URL": args.redis if backend == "postgres" else "filesystem://",
                "METAIRL_QUEUE_NAME": f"metairl-load-{secrets.token_hex(4)}",
                # One key floods on purpose: the limiter runs (its cost is measured) but never refuses.
                "METAIRL_RATE_LIMIT_PER_KEY": "1000000000",
            }
            targets = [
                Target("GET /healthz", "/healthz", 32, keyed=False),
                Target("GET /v1/jobs/{id}", f"/v1/jobs/{job_id}", 8),
                Target("GET /v1/jobs/{id}", f"/v1/jobs/{job_id}", 32),
                Target("GET /v1/rewards/{id}?format=npy", f"/v1/rewards/{reward_id}?format=npy", 32),
                Target("GET /v1/jobs/{id}/history", f"/v1/jobs/{job_id}/history", 2),
            ]
            if args.malloc_arena_max:
                env["MALLOC_ARENA_MAX"] = str(args.malloc_arena_max)
            with api(args, env) as (base, server):
                at_start = worker_rss_mb(server, workers=args.workers)
                for target in targets:
                    load = os.getloadavg()[0]
                    results = [wrk(base, target, key, args.duration) for _ in range(args.runs)]
                    rows.append(
                        {
                            "backend": backend,
                            "request": target.name,
                            "connections": target.connections,
                            "rps": statistics.median(r.rps for r in results),
                            "p50_ms": statistics.median(r.p50_ms for r in results),
                            "p99_ms": statistics.median(r.p99_ms for r in results),
                            "non_2xx": sum(r.errors for r in results),
                            "load_average": load,
                        }
                    )
                    lines.append(
                        f"| {backend} | `{target.name}` | {target.connections} "
                        f"| {statistics.median(r.rps for r in results):,.0f} "
                        f"| {statistics.median(r.p50_ms for r in results):.1f} "
                        f"| {statistics.median(r.p99_ms for r in results):.1f} "
                        f"| {sum(r.errors for r in results)} | {load:.2f} |"
                    )
                    print(lines[-1], flush=True)
                after = worker_rss_mb(server, workers=args.workers)
                rss_notes.append(f"{backend}: {megabytes(at_start)} MB at start, {megabytes(after)} MB after")
                rss[backend] = {"at_start": at_start, "after": after}

    lines += ["", f"API worker RSS (each process): {'; '.join(rss_notes)} the load.", ""]
    print("\n".join(lines))
    args.results.write_text(json.dumps({"provenance": run, "rows": rows, "rss_mb": rss}, indent=1) + "\n")
    return 0


def megabytes(sizes: list[float]) -> str:
    """Sizes in MB, comma separated."""
    return ", ".join(f"{mb:.0f}" for mb in sizes)


def versions(app_dir: Path) -> str:
    """Python, the web stack, wrk and the served commit."""
    parts = [f"Python {platform.python_version()}"]
    for name in PACKAGES:
        with contextlib.suppress(metadata.PackageNotFoundError):
            parts.append(f"{name} {metadata.version(name)}")
    done = subprocess.run(["wrk", "--version"], capture_output=True, text=True)
    parts.append(" ".join((done.stdout + done.stderr).split()[:2]))
    commit = subprocess.run(
        ["git", "-C", str(app_dir), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    )
    dirty = subprocess.run(
        ["git", "-C", str(app_dir), "status", "--porcelain"], capture_output=True, text=True
    )
    if commit.returncode == 0:
        parts.append(f"commit {commit.stdout.strip()}{'+changes' if dirty.stdout.strip() else ''}")
    return ", ".join(parts)


@contextlib.contextmanager
def database(backend: str, admin_url: str, *, label: str = "load") -> Iterator[tuple[str, Path]]:
    """A fresh database URL for `backend` and a temporary data folder, both removed afterwards.

    On PostgreSQL the database is ``metairl_<label>_<random>``, created through `admin_url` and dropped at the end.
    """
    data_dir = Path(tempfile.mkdtemp(prefix=f"metairl-{label}-"))
    try:
        if backend == "sqlite":
            yield f"sqlite:///{data_dir / 'metairl.db'}", data_dir
            return
        if backend != "postgres":
            sys.exit(f"unknown backend {backend!r} (postgres or sqlite)")
        import psycopg
        from psycopg import sql

        name = f"metairl_{label}_{secrets.token_hex(4)}"
        with psycopg.connect(admin_url, autocommit=True) as admin:
            admin.execute(sql.SQL("CREATE DATABASE {}").format(sql.Identifier(name)))
        try:
            server = admin_url.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://", 1)
            yield f"{server}/{name}", data_dir
        finally:
            with psycopg.connect(admin_url, autocommit=True) as admin:
                admin.execute(sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(name)))
    finally:
        shutil.rmtree(data_dir, ignore_errors=True)


def seed(url: str, data_dir: Path) -> tuple[str, str, str]:
    """A lab's key, a succeeded job with its 80,000-state baseline reward and its longest loss curve.

    Written through the API and the store layer, as a client and the worker would.
    """
    import numpy as np
    from fastapi.testclient import TestClient
    from sqlalchemy.orm import Session

    from metairl_engine.results import Progress
    from service.api.app import create_app
    from service.results.rewards import add_reward
    from service.settings import Settings
    from service.store.histories import add_step_history
    from service.store.ids import new_id
    from service.store.keys import add_key
    from service.store.models.job_status import JobStatus
    from service.store.models.jobs import Job

    app = create_app(Settings(database_url=url, data_dir=data_dir))
    with Session(app.state.engine) as session:
        key = add_key(session, "load")
        session.commit()
    auth = {"Authorization": f"Bearer {key}"}
    with TestClient(app) as client:
        grid = {"kind": "grid", "name": "plate", "width": 100, "height": 100, "velocity": True, "gamma": 0.9}
        mdp = checked(client.post("/v1/mdps", json=grid, headers=auth))
        assert mdp["n_states"] == N_STATES, mdp["n_states"]
        person = checked(client.post("/v1/demonstrators", json={"name": "patient 1"}, headers=auth))
        task = checked(
            client.post(
                f"/v1/demonstrators/{person['id']}/tasks",
                json={"name": "reach", "mdp_id": mdp["id"]},
                headers=auth,
            )
        )
    with app.state.sessionmaker() as session:
        job = Job(
            id=new_id("job"),
            lab_id=_lab_id(session, key),
            demonstrator_id=person["id"],
            task_ids=[task["id"]],
            config={},
            status=JobStatus.SUCCEEDED.value,
            cancel_requested=False,
            attempts=1,
            max_attempts=3,
        )
        session.add(job)
        session.flush()
        values = np.random.default_rng(0).normal(size=N_STATES).astype(np.float32)
        reward = add_reward(session, job, ordinal=0, n_actions=mdp["n_actions"], reward=values)
        # Losses falling as 1/step, a held-out NLL and elapsed time: numbers of every kind a fit reports.
        steps = [
            Progress(
                step,
                HISTORY_STEPS,
                2 / (step + 0.37),
                1.7 / (step + 0.37),
                0.3 / (step + 0.37),
                1 + 1 / step,
                0.013 * step,
            )
            for step in range(1, HISTORY_STEPS + 1)
        ]
        add_step_history(session, job.id, job.attempts, steps)
        session.commit()
        job_id, reward_id = job.id, reward.id
    app.state.engine.dispose()
    return key, job_id, reward_id


def _lab_id(session: object, key: str) -> str:
    """The lab of `key` (its id is the key's middle part)."""
    from sqlalchemy import select

    from service.store.models.labs import ApiKey

    key_id = key.split("_")[1]
    lab_id: str = session.execute(select(ApiKey.lab_id).where(ApiKey.id == key_id)).scalar_one()  # type: ignore[attr-defined]
    return lab_id


def checked(response: Any) -> dict[str, Any]:
    """The JSON body of a 201 response (anything else stops the benchmark with the body)."""
    status = response.status_code
    if status != 201:
        sys.exit(f"seeding failed: {status} {response.text}")
    body: dict[str, Any] = response.json()
    return body


@contextlib.contextmanager
def api(args: argparse.Namespace, env: dict[str, str]) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """uvicorn serving the app with `args.workers` processes on a free loopback port, stopped afterwards."""
    port = free_port()
    argv = [
        sys.executable, "-m", "uvicorn", "--factory", "service.api.app:create_app",
        "--host", "127.0.0.1", "--port", str(port), "--workers", str(args.workers),
        "--no-access-log", "--log-level", "warning", *shlex.split(args.uvicorn_args),
    ]  # fmt: skip
    server = subprocess.Popen(argv, cwd=args.app_dir, env=env, start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        wait_ready(base, server, workers=args.workers)
        yield base, server
    finally:
        server.terminate()
        try:
            server.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, 9)
            server.wait()


def free_port() -> int:
    """A loopback port nobody listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def wait_ready(base: str, server: subprocess.Popen[bytes], *, workers: int) -> None:
    """Until ``/readyz`` answers and every worker process is up (60 s at most), then a short warm-up."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if server.poll() is not None:
            sys.exit("the API exited during start-up")
        with contextlib.suppress(OSError), urllib.request.urlopen(f"{base}/readyz", timeout=1) as response:
            if response.status == 200 and len(children(server.pid)) >= workers:
                time.sleep(1.0)
                return
        time.sleep(0.2)
    sys.exit("the API did not become ready within 60 s")


def children(pid: int) -> list[int]:
    """The process ids whose parent is `pid` (the uvicorn workers; their multiprocessing helper too)."""
    found = []
    for status in Path("/proc").glob("[0-9]*/status"):
        with contextlib.suppress(OSError):
            text = status.read_text()
            if re.search(rf"^PPid:\s+{pid}$", text, re.M):
                found.append(int(status.parent.name))
    return found


def worker_rss_mb(server: subprocess.Popen[bytes], *, workers: int) -> list[float]:
    """Resident memory of each worker process (the largest children of the uvicorn supervisor), in MB."""
    sizes = []
    for pid in children(server.pid):
        with contextlib.suppress(OSError):
            match = re.search(r"^VmRSS:\s+(\d+) kB", Path(f"/proc/{pid}/status").read_text(), re.M)
            if match:
                sizes.append(int(match.group(1)) / 1024)
    return sorted(sizes, reverse=True)[:workers]


def wrk(base: str, target: Target, key: str, duration: int) -> Result:
    """One bounded wrk run against `target`."""
    argv = ["wrk", "-t2", f"-c{target.connections}", f"-d{duration}s", "--latency", "--timeout", "5s"]
    if target.keyed:
        argv += ["-H", f"Authorization: Bearer {key}"]
    done = subprocess.run([*argv, base + target.path], capture_output=True, text=True, timeout=duration + 30)
    out = done.stdout
    rps = re.search(r"Requests/sec:\s+([\d.]+)", out)
    if done.returncode != 0 or rps is None:
        sys.exit(f"wrk failed: {done.stdout}{done.stderr}")
    non2xx = re.search(r"Non-2xx or 3xx responses:\s+(\d+)", out)
    socket_errors = re.search(r"Socket errors: connect (\d+), read (\d+), write (\d+), timeout (\d+)", out)
    errors = int(non2xx.group(1)) if non2xx else 0
    if socket_errors:
        errors += sum(int(n) for n in socket_errors.groups())
    return Result(float(rps.group(1)), percentile(out, "50%"), percentile(out, "99%"), errors)


def percentile(out: str, which: str) -> float:
    """A latency percentile from wrk's ``--latency`` table, in milliseconds."""
    match = re.search(rf"^\s+{re.escape(which)}\s+([\d.]+)(us|ms|s)\s*$", out, re.M)
    if match is None:
        return float("nan")
    value, unit = float(match.group(1)), match.group(2)
    return value * {"us": 0.001, "ms": 1.0, "s": 1000.0}[unit]


if __name__ == "__main__":
    raise SystemExit(main())
