"""A real `metairl serve` (API + one worker on the embedded defaults) for end-to-end tests."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx

REPO = Path(__file__).resolve().parents[1]
KEY_NOTICE = "API key for lab"
"""`metairl serve` prints this line, then the key alone on the next line."""


def free_port() -> int:
    """A TCP port nobody listens on right now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass(frozen=True)
class Served:
    """A running `metairl serve`: its base URL, the printed API key, the process and its output file."""

    url: str
    key: str
    proc: subprocess.Popen[bytes]
    log: Path


@contextlib.contextmanager
def metairl_serve(
    folder: Path, *, timeout_s: float = 90.0, settings: dict[str, str] | None = None
) -> Iterator[Served]:
    """Start `metairl serve` on a free port with its data in ``folder/var`` and the given ``METAIRL_*``
    settings (none of this process's); SIGTERM (then kill) on exit."""
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
    env["METAIRL_DATA_DIR"] = str(folder / "var")
    env |= settings or {}
    log = folder / "serve.log"
    with log.open("wb") as sink:
        proc = subprocess.Popen(
            [sys.executable, "-m", "metairl_cli", "serve", "--port", str(port)],
            cwd=REPO,
            env=env,
            stdout=sink,
            stderr=subprocess.STDOUT,
        )
    try:
        url = f"http://127.0.0.1:{port}"
        yield Served(url=url, key=_wait_for_key(url, log, proc, timeout_s=timeout_s), proc=proc, log=log)
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def _wait_for_key(url: str, log: Path, proc: subprocess.Popen[bytes], *, timeout_s: float) -> str:
    """Wait for /healthz to answer and for the API key to be printed (the line after the notice)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"metairl serve exited:\n{log.read_text()}"
        lines = log.read_text(errors="replace").splitlines()
        notice = [i for i, line in enumerate(lines) if line.startswith(KEY_NOTICE)]
        if notice and len(lines) > notice[0] + 1:
            assert httpx.get(f"{url}/healthz").status_code == 200
            return lines[notice[0] + 1].strip()
        time.sleep(0.2)
    raise AssertionError(f"metairl serve did not start within {timeout_s} s:\n{log.read_text()}")
