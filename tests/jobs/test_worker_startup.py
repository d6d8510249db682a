"""A real `metairl worker` started before the database is migrated waits, saying so once, and consumes once it
is migrated; on a database migrated by newer code it exits saying so (README, "Scaling out")."""

from __future__ import annotations

import contextlib
import os
import secrets
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import text

from service.jobs.broker import delete_queue
from service.settings import Settings
from service.store.db import make_engine, migrate
from tests.conftest import fresh_database
from tests.jobs.conftest import BROKERS, FAST, REPO, settings_environment
from worker.startup import POLL_S

pytestmark = [pytest.mark.worker, pytest.mark.slow]

WAITING = "waiting for the database"


@pytest.fixture(
    params=[
        "embedded",
        pytest.param("redis_pg", marks=[pytest.mark.redis, pytest.mark.postgres]),
    ]
)
def unmigrated(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Settings]:
    """Settings of a stack whose database was never migrated: a SQLite file not yet there (embedded broker),
    or an empty PostgreSQL database (Redis)."""
    options: dict[str, object] = {
        "data_dir": tmp_path / "var",
        "queue_name": f"metairl-test-{secrets.token_hex(4)}",
    }
    with contextlib.ExitStack() as stack:
        if request.param in BROKERS:
            url = stack.enter_context(fresh_database("postgres", tmp_path))
            options |= {"database_url": url, "broker_url": BROKERS[request.param]}
        settings = Settings(**options, **FAST)  # type: ignore[arg-type]
        yield settings
        if request.param in BROKERS:
            delete_queue(settings)


@contextlib.contextmanager
def worker_process(settings: Settings, log: Path) -> Iterator[subprocess.Popen[bytes]]:
    """`metairl worker` on these settings, its output in `log`; it and its pool are killed afterwards."""
    with open(log, "wb") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", "metairl_cli.main", "worker", "--concurrency", "1"],
            cwd=REPO,
            env=settings_environment(settings),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    try:
        yield process
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=10)


def wait_for(log: Path, needle: str, process: subprocess.Popen[bytes], timeout: float = 60) -> None:
    """Until `needle` shows in the worker's output; fails if the worker exits or the time runs out."""
    deadline = time.monotonic() + timeout
    while needle not in log.read_text(errors="replace"):
        assert process.poll() is None, f"worker exited: {log.read_text()}"
        assert time.monotonic() < deadline, f"no {needle!r} after {timeout} s: {log.read_text()}"
        time.sleep(0.1)


def test_a_worker_started_before_the_migration_waits_saying_so_once_then_consumes(
    unmigrated: Settings, tmp_path: Path
) -> None:
    log = tmp_path / "worker.log"
    sqlite_file = unmigrated.data_dir / "metairl.db"
    with worker_process(unmigrated, log) as process:
        wait_for(log, WAITING, process)
        time.sleep(2 * POLL_S + 1)  # several more looks, and a reaper interval or more
        output = log.read_text()
        assert output.count(WAITING) == 1, output
        assert "Traceback" not in output and " ready." not in output, output
        assert process.poll() is None
        if unmigrated.database_url is None:
            assert not sqlite_file.exists()  # no empty database left behind

        engine = make_engine(unmigrated)
        migrate(engine)  # what the API does at start-up
        engine.dispose()
        wait_for(log, " ready.", process)
        assert "Traceback" not in log.read_text()


def test_a_worker_on_a_database_migrated_by_newer_code_exits_saying_so(tmp_path: Path) -> None:
    settings = Settings(data_dir=tmp_path / "var", queue_name=f"metairl-test-{secrets.token_hex(4)}")
    engine = make_engine(settings)
    migrate(engine)
    with engine.begin() as connection:
        connection.execute(text("UPDATE alembic_version SET version_num = '9999_from_newer_code'"))
    engine.dispose()
    log = tmp_path / "worker.log"
    with worker_process(settings, log) as process:
        code = process.wait(timeout=60)
    output = log.read_text()
    assert code == 1, output
    assert "migrated by a newer metairl" in output and " ready." not in output
