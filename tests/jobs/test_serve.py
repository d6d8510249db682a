"""`metairl serve`: one command starts API and worker on the embedded defaults and stops both on SIGTERM."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import httpx
import pytest

from metairl_cli.serve import (
    WORKER_MAX_BACKOFF_S,
    WORKER_STABLE_S,
    WorkerRestarts,
    api_command,
    default_api_workers,
)
from tests.served import metairl_serve

pytestmark = [pytest.mark.worker, pytest.mark.slow]


def children_of(pid: int) -> list[int]:
    """Direct child processes of ``pid`` (Linux /proc)."""
    return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


def test_serve_starts_api_and_worker_answers_and_stops_cleanly_on_sigterm(tmp_path: Path) -> None:
    with metairl_serve(tmp_path) as served:
        lines = served.log.read_text().splitlines()
        assert f"API docs: {served.url}/docs" in lines
        assert httpx.get(f"{served.url}/healthz").json() == {"status": "ok"}
        assert httpx.get(f"{served.url}/docs").status_code == 200
        assert (
            httpx.get(f"{served.url}/v1/jobs", headers={"Authorization": f"Bearer {served.key}"}).status_code
            == 200
        )
        assert (tmp_path / "var" / "metairl.db").is_file() and (
            tmp_path / "var" / "broker" / "queue"
        ).is_dir()
        children = children_of(served.proc.pid)
        assert len(children) == 2
        # Quiet: its own four lines, the key last; no banner, no INFO lines of Celery or uvicorn, no access log.
        assert lines[0].startswith(f"metairl is running at {served.url}")
        assert lines[1:] == [f"API docs: {served.url}/docs", lines[2], served.key]
        assert lines[2].startswith("API key for lab 'local'")

        served.proc.send_signal(signal.SIGTERM)
        assert served.proc.wait(timeout=30) == 0, served.log.read_text()
        for pid in children:
            with pytest.raises(ProcessLookupError):
                os.kill(pid, 0)
        with pytest.raises(httpx.ConnectError):
            httpx.get(f"{served.url}/healthz")


def test_serve_runs_one_api_process_per_core_on_uvloop_and_httptools() -> None:
    argv = api_command("python", host="127.0.0.1", port=8000, workers=default_api_workers())
    assert argv[argv.index("--workers") + 1] == str(len(os.sched_getaffinity(0)))
    assert argv[argv.index("--loop") + 1] == "uvloop" and argv[argv.index("--http") + 1] == "httptools"


def worker_child(pid: int) -> int | None:
    """The pid of `serve`'s worker child (its command line runs ``metairl_cli.main worker``), if any."""
    for child in children_of(pid):
        try:
            argv = Path(f"/proc/{child}/cmdline").read_bytes().split(b"\0")
        except FileNotFoundError:
            continue
        if b"worker" in argv and b"metairl_cli.main" in argv:
            return child
    return None


def test_a_killed_worker_is_restarted_while_the_api_stays_up(tmp_path: Path) -> None:
    with metairl_serve(tmp_path) as served:
        first = worker_child(served.proc.pid)
        assert first is not None
        os.kill(first, signal.SIGKILL)
        deadline = time.monotonic() + 30
        second = None
        while time.monotonic() < deadline:
            assert httpx.get(f"{served.url}/healthz").status_code == 200  # the API never went away
            second = worker_child(served.proc.pid)
            if second not in (None, first):
                break
            time.sleep(0.2)
        assert second not in (None, first), served.log.read_text()
        assert served.proc.poll() is None
        assert "the worker exited with code -9; restarting it in 1 s" in served.log.read_text()
        served.proc.send_signal(signal.SIGTERM)
        assert served.proc.wait(timeout=30) == 0, served.log.read_text()


def test_worker_restarts_back_off_and_start_over_after_a_stable_run() -> None:
    restarts = WorkerRestarts()
    delays = [restarts.next_delay(now) for now in (100.0, 101.5, 104.0, 109.0, 118.0, 135.0, 166.0)]
    assert delays == [1.0, 2.0, 4.0, 8.0, 16.0, WORKER_MAX_BACKOFF_S, WORKER_MAX_BACKOFF_S]
    assert restarts.next_delay(166.0 + WORKER_MAX_BACKOFF_S + WORKER_STABLE_S) == 1.0
