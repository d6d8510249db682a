"""The `metairl` command line: version, help with examples, and a quiet `serve` that prints its key last."""

from __future__ import annotations

import sys
from importlib.metadata import version
from pathlib import Path

import pytest

from metairl_cli.main import EXAMPLES, build_parser, main
from metairl_cli.serve import api_command, spawn_relayed, worker_command


def test_version_prints_the_installed_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["--version"])
    assert stopped.value.code == 0
    assert capsys.readouterr().out.strip() == f"metairl {version('metairl')}"


@pytest.mark.parametrize("command", ["serve", "worker", "keys", "demo"])
def test_each_commands_help_ends_with_examples_of_it(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args([command, "--help"])
    text = capsys.readouterr().out
    examples = text.split("examples:\n", 1)[1]
    assert examples.strip() == EXAMPLES[command].split("examples:\n", 1)[1].strip()
    assert all(f"metairl {command}" in line for line in examples.splitlines() if line.startswith("  "))


def test_the_top_help_lists_examples(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    assert "metairl serve" in capsys.readouterr().out.split("examples:", 1)[1]


def test_serve_runs_uvicorn_without_access_log_unless_asked() -> None:
    assert "--no-access-log" in api_command("python", host="h", port=1, workers=1)
    loud = api_command("python", host="h", port=1, workers=1, access_log=True)
    assert "--access-log" in loud and "--no-access-log" not in loud
    assert build_parser().parse_args(["serve", "--access-log"]).access_log
    assert not build_parser().parse_args(["serve"]).access_log


def test_serve_starts_its_worker_without_the_celery_banner(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    assert worker_command("python")[-1] == "--quiet"
    monkeypatch.chdir(tmp_path)  # the Celery app makes its broker folders under ./var on import
    from worker import main as worker_main
    from worker.celery_app import app

    monkeypatch.setenv("METAIRL_WORKER_CONCURRENCY", "1")
    started: list[list[str]] = []
    monkeypatch.setattr(app, "start", lambda argv: started.append(argv))
    worker_main.run_worker(concurrency=1, quiet=True)
    worker_main.run_worker(concurrency=1)
    assert started[0][:2] == ["--quiet", "worker"] and started[1][0] == "worker"


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


def test_the_worker_output_is_relayed_and_its_ready_line_noticed(capfd: pytest.CaptureFixture[str]) -> None:
    code = "import time; print('banner', flush=True); time.sleep(0.2); print('[INFO] celery@x ready.', flush=True)"
    child, ready = spawn_relayed([sys.executable, "-c", code], {})
    assert not ready.is_set()
    assert ready.wait(10)
    child.wait(10)
    assert "banner\n[INFO] celery@x ready.\n" in capfd.readouterr().err
