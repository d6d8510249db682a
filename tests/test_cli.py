"""The `metairl` command line: version, help with examples, and a quiet `serve` that prints its key last."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import time
from importlib.metadata import version
from pathlib import Path

import pytest

from metairl_cli.main import EXAMPLES, build_parser, main
from metairl_cli.serve import api_command, child_environment, spawn_relayed, worker_command
from service.settings import Settings


def test_version_prints_the_installed_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["--version"])
    assert stopped.value.code == 0
    assert capsys.readouterr().out.strip() == f"metairl {version('metairl')}"


@pytest.mark.parametrize(
    "command", ["serve", "worker", "keys", "keys create", "keys list", "keys revoke", "demo"]
)
def test_each_commands_help_ends_with_examples_of_it(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args([*command.split(), "--help"])
    text = capsys.readouterr().out
    examples = text.split("examples:\n", 1)[1]
    assert examples.strip() == EXAMPLES[command].split("examples:\n", 1)[1].strip()
    assert all(f"metairl {command}" in line for line in examples.splitlines() if line.startswith("  "))


def test_the_top_help_lists_examples(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    assert "metairl serve" in capsys.readouterr().out.split("examples:", 1)[1]


def test_serve_runs_uvicorn_without_access_log_or_info_lines_unless_asked() -> None:
    quiet = api_command("python", host="h", port=1, workers=1)
    assert "--no-access-log" in quiet and quiet[quiet.index("--log-level") + 1] == "warning"
    loud = api_command("python", host="h", port=1, workers=1, access_log=True)
    assert "--access-log" in loud and "--no-access-log" not in loud
    assert loud[loud.index("--log-level") + 1] == "info"  # uvicorn's level gates its access log too
    assert build_parser().parse_args(["serve", "--access-log"]).access_log
    assert not build_parser().parse_args(["serve"]).access_log


@pytest.fixture
def started(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> list[list[str]]:
    """The arguments each `run_worker` call hands Celery, which starts nothing."""
    monkeypatch.chdir(tmp_path)  # the Celery app makes its broker folders under ./var on import
    from worker.celery_app import app

    monkeypatch.setenv("METAIRL_WORKER_CONCURRENCY", "1")
    calls: list[list[str]] = []
    monkeypatch.setattr(app, "start", lambda argv: calls.append(argv))
    return calls


def test_serve_starts_its_worker_without_the_celery_banner(started: list[list[str]]) -> None:
    assert worker_command("python")[-1] == "--quiet"
    from worker import main as worker_main

    worker_main.run_worker(concurrency=1, quiet=True)
    worker_main.run_worker(concurrency=1)
    assert started[0][:2] == ["--quiet", "worker"] and started[1][0] == "worker"
    assert "--loglevel=WARNING" in started[0] and "--loglevel=INFO" in started[1]


def test_a_worker_named_on_the_command_line_starts_under_that_celery_node_name(
    started: list[list[str]],
) -> None:
    from worker import main as worker_main

    args = build_parser().parse_args(["worker", "--name", "second@%h"])
    worker_main.run_worker(concurrency=args.concurrency, quiet=args.quiet, name=args.name)
    worker_main.run_worker(concurrency=1)
    assert "--hostname=second@%h" in started[0]
    assert not any(arg.startswith("--hostname") for arg in started[1])


def test_a_quiet_worker_says_it_is_ready_on_the_real_stdout(capfd: pytest.CaptureFixture[str]) -> None:
    from worker.main import announce_ready

    class Consumer:
        hostname = "celery@x"

    announce_ready(Consumer())
    assert capfd.readouterr().out == "celery@x ready.\n"


CHECK_PRIVILEGES_AS_ROOT = """
import os, sys
os.getuid = os.geteuid = lambda: 0
from celery.platforms import check_privileges
check_privileges({sys.argv[1]})
"""
"""Celery's check of a worker's privileges, as it runs at a worker's start by root, for the content named."""


def test_serve_starts_its_worker_without_celerys_root_warning_but_keeps_its_root_error() -> None:
    python_flags = worker_command(sys.executable)[:3]  # the interpreter and its options, up to ``-m``

    def as_root(content: str, flags: list[str]) -> subprocess.CompletedProcess[str]:
        argv = [*flags, "-c", CHECK_PRIVILEGES_AS_ROOT, content]
        env = {k: v for k, v in os.environ.items() if k not in ("C_FORCE_ROOT", "PYTHONWARNINGS")}
        return subprocess.run(argv, capture_output=True, text=True, timeout=60, env=env)

    assert "superuser privileges" in as_root("json", [sys.executable]).stderr  # what the filter is for
    assert as_root("json", python_flags).stderr == ""
    refused = as_root("pickle", python_flags)
    assert refused.returncode != 0 and "SecurityError" in refused.stderr


def test_the_embedded_broker_names_its_host_so_kombu_does_not_warn(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from kombu import Connection

    from service.jobs.broker import broker_url

    settings = Settings(data_dir=tmp_path, broker_url=None)
    url = broker_url(settings)  # a worker alone, and the API
    assert url.startswith("filesystem://") and child_environment(settings)["METAIRL_BROKER_URL"] == url
    with caplog.at_level(logging.WARNING, logger="kombu"):
        Connection(url).as_uri()  # what the worker logs on connecting
    assert caplog.records == []


def test_a_worker_without_concurrency_takes_the_setting_from_the_environment(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)  # the Celery app makes its broker folders under ./var on import
    from worker import main as worker_main
    from worker.celery_app import app

    monkeypatch.setenv("METAIRL_WORKER_CONCURRENCY", "3")
    started: list[list[str]] = []
    monkeypatch.setattr(app, "start", lambda argv: started.append(argv))
    assert build_parser().parse_args(["worker"]).concurrency is None
    worker_main.run_worker()
    worker_main.run_worker(concurrency=2)
    assert "--concurrency=3" in started[0] and "--concurrency=2" in started[1]


def test_the_worker_output_is_relayed_and_its_ready_line_noticed_not_relayed(
    capfd: pytest.CaptureFixture[str],
) -> None:
    code = (
        "import time; print('warning', flush=True); time.sleep(0.2); print('celery@x ready.', flush=True); "
        "print('error', flush=True)"
    )
    child, ready = spawn_relayed([sys.executable, "-c", code], {})
    assert not ready.is_set()
    assert ready.wait(10)
    child.wait(10)
    err, deadline = "", time.monotonic() + 10
    while not err.endswith("error\n") and time.monotonic() < deadline:  # the relay thread's last line
        time.sleep(0.05)
        err += capfd.readouterr().err
    assert err == "warning\nerror\n"
