"""`metairl keys list` and `metairl keys revoke` (docs/api.md, "Conventions": managing keys), and the `local` key that `metairl serve` keeps
between starts instead of minting a new one each time."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy import inspect, text

from metairl_cli.keys import create_key
from metairl_cli.serve import LOCAL_KEY_FILE, local_key
from service.settings import Settings
from service.store.db import database_state, make_engine, migrate
from service.store.keys import add_key, list_keys, revoke_key, split_key

REPO = Path(__file__).resolve().parents[2]


def metairl(settings: Settings, *args: str) -> subprocess.CompletedProcess[str]:
    """Run the `metairl` command on the test's database."""
    return metairl_with(
        {"METAIRL_DATA_DIR": str(settings.data_dir), "METAIRL_DATABASE_URL": settings.resolved_database_url},
        *args,
    )


def metairl_with(settings: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    """Run the `metairl` command with exactly these ``METAIRL_*`` settings in its environment."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")} | settings
    return subprocess.run(
        [sys.executable, "-m", "metairl_cli.main", *args],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


def key_id(key: str) -> str:
    """The public id part of a full key."""
    parts = split_key(key)
    assert parts is not None
    return parts[0]


def test_list_shows_each_key_of_a_lab_and_revoke_makes_the_next_request_401(
    settings: Settings, app: FastAPI, client: TestClient, api_key: str
) -> None:
    with app.state.sessionmaker() as session:
        lab = next(k.lab for k in list_keys(session) if k.id == key_id(api_key))
        second = create_key(session, lab)
    auth = {"Authorization": f"Bearer {api_key}"}
    assert client.get("/v1/demonstrators", headers=auth).status_code == 200

    listed = metairl(settings, "keys", "list", "--lab", lab)
    assert listed.returncode == 0, listed.stderr
    lines = listed.stdout.strip().splitlines()
    assert len(lines) == 2
    rows = {line.split("\t")[0]: line.split("\t") for line in lines}
    first_row, second_row = rows[key_id(api_key)], rows[key_id(second)]
    assert first_row[1] == lab and len(first_row) == 5
    assert first_row[2].endswith("Z") and first_row[3].endswith("Z") and first_row[4] == "-"
    assert second_row[3] == "never" and second_row[4] == "-"
    assert api_key.split("_")[-1] not in listed.stdout  # no secret is ever listed

    revoked = metairl(settings, "keys", "revoke", key_id(api_key))
    assert revoked.returncode == 0, revoked.stdout + revoked.stderr
    response = client.get("/v1/demonstrators", headers=auth)
    assert response.status_code == 401 and "revoked" in response.json()["detail"]
    assert client.get("/v1/demonstrators", headers={"Authorization": f"Bearer {second}"}).status_code == 200
    after = {
        line.split("\t")[0]: line.split("\t")
        for line in metairl(settings, "keys", "list").stdout.splitlines()
    }
    assert after[key_id(api_key)][4].endswith("Z") and after[key_id(second)][4] == "-"

    unknown = metairl(settings, "keys", "revoke", "0123456789abcdef")
    assert unknown.returncode == 1 and "no API key" in unknown.stderr and unknown.stdout == ""
    nobody = metairl(settings, "keys", "list", "--lab", "no such lab")
    assert nobody.returncode == 1 and "has no API keys" in nobody.stderr and nobody.stdout == ""


def test_list_and_revoke_on_a_mistyped_data_dir_say_so_on_stderr_and_create_nothing(tmp_path: Path) -> None:
    """Where `keys list` printed nothing and exited 0 on a new empty database; `keys create` still starts one."""
    folder = tmp_path / "mistyped"
    database = folder / "metairl.db"
    for args in (
        ("keys", "list"),
        ("keys", "list", "--lab", "local"),
        ("keys", "revoke", "0123456789abcdef"),
    ):
        refused = metairl_with({"METAIRL_DATA_DIR": str(folder)}, *args)
        assert refused.returncode == 1 and refused.stdout == "", args
        assert refused.stderr.splitlines() == [refused.stderr.strip()], args  # one line
        assert f"no metairl database at {database}" in refused.stderr, args
        assert not folder.exists(), args

    created = metairl_with({"METAIRL_DATA_DIR": str(folder)}, "keys", "create", "--lab", "new-lab")
    assert created.returncode == 0 and created.stderr == "", created.stderr
    listed = metairl_with({"METAIRL_DATA_DIR": str(folder)}, "keys", "list")
    assert listed.returncode == 0 and [line.split("\t")[1] for line in listed.stdout.splitlines()] == [
        "new-lab"
    ]
    assert key_id(created.stdout.splitlines()[-1]) == listed.stdout.split("\t")[0]


def test_list_refuses_a_database_without_the_schema_and_leaves_it_so(empty_database_url: str) -> None:
    """On each backend: an existing but never migrated database (a mistyped PostgreSQL URL's) is not migrated."""
    listed = metairl_with({"METAIRL_DATABASE_URL": empty_database_url}, "keys", "list")
    assert listed.returncode == 1 and listed.stdout == ""
    assert "no metairl database at" in listed.stderr
    engine = make_engine(Settings(database_url=empty_database_url))
    assert database_state(Settings(database_url=empty_database_url)) == "empty"
    assert inspect(engine).get_table_names() == []
    engine.dispose()


def test_create_and_serve_refuse_a_database_migrated_by_newer_code_in_one_line(tmp_path: Path) -> None:
    """A schema this code does not know is named on stderr, not as Alembic's traceback, and left unchanged."""
    settings = Settings(data_dir=tmp_path)
    engine = make_engine(settings)
    migrate(engine)
    with engine.begin() as connection:
        connection.execute(text("UPDATE alembic_version SET version_num = '9999_from_newer_code'"))
    env = {"METAIRL_DATA_DIR": str(tmp_path)}
    created = metairl_with(env, "keys", "create", "--lab", "gait")
    served = metairl_with(env, "serve", "--port", "0")
    for refused in (created, served):
        assert refused.returncode == 1 and refused.stdout == "", refused.stderr
        assert refused.stderr.count("\n") == 1 and "migrated by a newer metairl" in refused.stderr
    assert database_state(settings) == "ahead"
    engine.dispose()


def test_an_empty_lab_name_is_refused_on_stderr() -> None:
    refused = metairl_with({}, "keys", "create", "--lab", "  ")
    assert refused.returncode == 2 and refused.stdout == "" and "--lab must not be empty" in refused.stderr


def test_serve_keeps_the_local_key_and_mints_a_new_one_only_when_it_is_revoked(
    app: FastAPI, tmp_path: Path
) -> None:
    data_dir = tmp_path / "data"
    with app.state.sessionmaker() as session:
        before = len(list_keys(session, lab_name="local"))
        first = local_key(session, data_dir)
        path = data_dir / LOCAL_KEY_FILE
        assert path.read_text().strip() == first
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
        assert local_key(session, data_dir) == first  # a second start prints the same key
        assert len(list_keys(session, lab_name="local")) == before + 1

    with app.state.sessionmaker() as session:
        revoke_key(session, key_id(first))
        session.commit()
        third = local_key(session, data_dir)
        assert third != first and path.read_text().strip() == third
        assert len(list_keys(session, lab_name="local")) == before + 2


def test_a_full_key_with_a_mistyped_secret_revokes_nothing(app: FastAPI) -> None:
    with app.state.sessionmaker() as session:
        key = add_key(session, "typo lab")
        wrong = key[:-4] + ("aaaa" if not key.endswith("aaaa") else "bbbb")
        assert revoke_key(session, wrong) is None
        assert [k.revoked_at for k in list_keys(session, lab_name="typo lab")] == [None]
        row = revoke_key(session, key)
        assert row is not None and row.revoked_at is not None
