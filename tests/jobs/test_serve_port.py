"""`metairl serve --port P` with P already taken fails at once with one line naming the port, before it
prints an address or a key, and creates nothing."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

from metairl_cli.serve import port_problem

REPO = Path(__file__).resolve().parents[2]


def test_serve_on_a_busy_port_fails_clearly_before_printing_anything(tmp_path: Path) -> None:
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
        env["METAIRL_DATA_DIR"] = str(tmp_path / "var")
        done = subprocess.run(
            [sys.executable, "-m", "metairl_cli", "serve", "--port", str(port)],
            cwd=REPO,
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert done.returncode == 2, done
    assert done.stdout == ""  # no "running at", no key
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and str(port) in lines[0] and "in use" in lines[0], done.stderr
    assert not (tmp_path / "var").exists()  # no database, no key file


def test_a_free_port_has_no_problem() -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    assert port_problem("127.0.0.1", port) is None
    assert port_problem("no-such-host.invalid", port) is not None
