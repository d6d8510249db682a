"""Alembic: the migrations build exactly the models' schema, go down and up again, and concurrent starts
migrate safely."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import func, inspect, select, text

import service.store.models
from service.settings import Settings
from service.store.db import (
    NewerSchema,
    alembic_config,
    database_state,
    head_revision,
    make_engine,
    make_sessionmaker,
    migrate,
    schema_state,
)
from service.store.models.demonstrators import Demonstrator
from service.store.models.jobs import Job, JobEvent
from service.store.models.labs import Lab


def test_migrations_match_the_models(settings: Settings) -> None:
    engine = make_engine(settings)
    migrate(engine)
    with engine.connect() as connection:
        context = MigrationContext.configure(connection, opts={"compare_type": True})
        diff = compare_metadata(context, service.store.models.Base.metadata)
    engine.dispose()
    assert diff == []


def test_downgrade_to_base_and_upgrade_again(empty_database_url: str) -> None:
    engine = make_engine(Settings(database_url=empty_database_url))
    migrate(engine)
    with engine.connect() as connection:
        command.downgrade(alembic_config(connection), "base")
        connection.commit()
    assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
    migrate(engine)
    assert {"labs", "mdps", "tasks", "demonstrations"} <= set(inspect(engine).get_table_names())
    engine.dispose()


def test_processes_starting_together_all_migrate(empty_database_url: str) -> None:
    engines = [make_engine(Settings(database_url=empty_database_url)) for _ in range(3)]
    errors: list[BaseException] = []

    def run(index: int) -> None:
        try:
            migrate(engines[index])
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(engines))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    assert "mdps" in inspect(engines[0]).get_table_names()
    for engine in engines:
        engine.dispose()


def test_the_head_read_from_the_files_is_alembics_and_a_current_database_is_left_alone(
    empty_database_url: str,
) -> None:
    """`migrate` skips Alembic when the database is stamped with the head it reads from the migration files."""
    engine = make_engine(Settings(database_url=empty_database_url))
    with engine.connect() as connection:
        assert head_revision() == ScriptDirectory.from_config(alembic_config(connection)).get_current_head()
    assert schema_state(engine) != "current"
    migrate(engine)
    assert schema_state(engine) == "current"
    with engine.begin() as connection:
        command.downgrade(alembic_config(connection), "-1")
    assert schema_state(engine) != "current"
    migrate(engine)
    assert schema_state(engine) == "current"
    engine.dispose()


def test_removing_the_shrinkage_and_sparsity_columns_keeps_every_jobs_rows(empty_database_url: str) -> None:
    """Going down from ``0013_sparsity`` and ``0012_shrinkage`` drops the columns in place: a copy of the jobs table (SQLite's batch
    mode) would delete every job's events, rewards and steps with the old table."""
    engine = make_engine(Settings(database_url=empty_database_url))
    migrate(engine)
    job = Job(
        id="job_migrations",
        lab_id="lab_migrations",
        demonstrator_id="dem_migrations",
        task_ids=[],
        config={},
        max_attempts=1,
        shrinkage=0.5,
        sparsity=0.9,
    )
    rows = [
        Lab(id="lab_migrations", name="migrations"),
        Demonstrator(id="dem_migrations", lab_id="lab_migrations", name="d"),
        job,
        JobEvent(job_id=job.id, kind="status", attempt=1),
    ]
    with make_sessionmaker(engine)() as session:
        for row in rows:  # parents first: the models declare no relationships to order them by
            session.add(row)
            session.flush()
        session.commit()
    with engine.connect() as connection:
        command.downgrade(alembic_config(connection), "0011_step_history")
        connection.commit()
    assert not {"shrinkage", "sparsity"} & {c["name"] for c in inspect(engine).get_columns("jobs")}
    with engine.connect() as connection:
        assert connection.execute(select(func.count()).select_from(JobEvent.__table__)).scalar_one() == 1
    migrate(engine)
    with make_sessionmaker(engine)() as session:
        assert session.get_one(Job, "job_migrations").shrinkage is None
    engine.dispose()


def test_a_database_is_told_empty_behind_current_or_ahead_of_this_code(empty_database_url: str) -> None:
    """What a worker waits on (`empty`, `behind`) and refuses (`ahead`: stamped by newer code, which `migrate`
    leaves as it is), on each backend."""
    settings = Settings(database_url=empty_database_url)
    assert database_state(settings) == "empty"
    engine = make_engine(settings)
    with engine.connect() as connection:
        previous = ScriptDirectory.from_config(alembic_config(connection)).get_revision("head").down_revision
        command.upgrade(alembic_config(connection), str(previous))
        connection.commit()
    assert database_state(settings) == "behind"
    migrate(engine)
    assert database_state(settings) == "current"
    with engine.begin() as connection:
        connection.execute(text("UPDATE alembic_version SET version_num = '9999_from_newer_code'"))
    assert database_state(settings) == "ahead"
    with pytest.raises(NewerSchema, match="migrated by a newer metairl"):
        migrate(engine)
    with engine.connect() as connection:
        assert (
            connection.execute(text("SELECT version_num FROM alembic_version")).scalar_one()
            == "9999_from_newer_code"
        )
    engine.dispose()


def test_the_state_of_a_sqlite_file_that_does_not_exist_is_empty_and_creates_nothing(tmp_path: Path) -> None:
    """Asking never creates the file (nor its folder): a worker on a mistyped data folder leaves no database."""
    folder = tmp_path / "mistyped"
    assert database_state(Settings(data_dir=folder)) == "empty"
    assert not folder.exists()
