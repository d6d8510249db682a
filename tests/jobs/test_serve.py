"""`metairl serve`: one command starts API and worker on the embedded defaults and stops both on SIGTERM."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import httpx
import pytest

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

        served.proc.send_signal(signal.SIGTERM)
        assert served.proc.wait(timeout=30) == 0, served.log.read_text()
        for pid in children:
            with pytest.raises(ProcessLookupError):
                os.kill(pid, 0)
        with pytest.raises(httpx.ConnectError):
            httpx.get(f"{served.url}/healthz")
