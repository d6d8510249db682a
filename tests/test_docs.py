"""The documentation's examples are executed, so they cannot rot.

- Python: the fenced blocks marked ``python`` in README.md, docs/api.md and docs/client.md run in order, in one namespace
  per file, against the in-process app (``httpx.Client`` is swapped for FastAPI's TestClient, which takes
  the same ``base_url`` and ``headers``). Blocks marked ``python worker`` need a job to finish: the first
  test stops before them, a second (``@pytest.mark.worker``) runs every block with a real worker process.
- Shell: every ``curl`` line's path and method must exist in the app's OpenAPI.
- Configuration: every `Settings` field is a row ``METAIRL_<NAME>`` of README's table, with its default;
  every ``METAIRL_*`` the docs mention is a setting (or a documented extra).
- Relative links in README and docs/ point at files that exist.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shlex
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings

REPO = Path(__file__).resolve().parents[1]
EXECUTED = ("README.md", "docs/api.md", "docs/client.md")
"""Files whose ``python`` blocks are executed."""
DOCUMENTED = ("README.md", "docs/api.md", "docs/architecture.md")
"""Files written for these tests: their curl lines, METAIRL_* names and links are checked."""
EXTRA_VARIABLES = {"METAIRL_API_KEY"}
"""Environment variables the docs name that are not `Settings` fields (read by `metairl demo`)."""
FENCE = re.compile(r"^```(?P<info>[^\n`]*)\n(?P<body>.*?)^```[ \t]*$", re.M | re.S)
PAGES = (
    *DOCUMENTED,
    *sorted({f"docs/{page.name}" for page in (REPO / "docs").glob("*.md")} - set(DOCUMENTED)),
    "benchmarks/RESULTS.md",
    "benchmarks/MOTION.md",
)
"""Every documentation page: their relative links must resolve and they must name no machine paths."""


@dataclass(frozen=True)
class Block:
    """One fenced code block: its file, first line number, info-string words and text."""

    path: str
    line: int
    tags: tuple[str, ...]
    code: str

    @property
    def where(self) -> str:
        """``file:line`` of the block, for failure messages."""
        return f"{self.path}:{self.line}"


def blocks(path: str, language: str | None = None) -> list[Block]:
    """The fenced blocks of a repo file, in order; only those of ``language`` if given."""
    text = (REPO / path).read_text(encoding="utf-8")
    found = []
    for match in FENCE.finditer(text):
        words = tuple(match["info"].split())
        if language is None or (words and words[0] == language):
            line = text.count("\n", 0, match.start()) + 2
            found.append(Block(path, line, words[1:], match["body"]))
    return found


def run_blocks(python: list[Block], app: FastAPI, api_key: str, *, with_worker: bool) -> dict[str, Any]:
    """Execute python blocks in order in one namespace (``worker`` blocks only if ``with_worker``);
    returns the namespace. ``httpx.Client(...)`` in the blocks gets a TestClient of ``app``,
    and ``METAIRL_API_KEY`` is ``api_key``. A failing block's traceback names its file and line."""
    assert python, "no python blocks"
    unknown = {tag for b in python for tag in b.tags} - {"worker"}
    assert not unknown, f"{python[0].path}: unknown python block tags {unknown}"
    namespace: dict[str, Any] = {"__name__": f"docs:{python[0].path}"}
    clients: list[TestClient] = []

    def client_factory(*, base_url: str = "http://testserver", headers: Any = None, **_: Any) -> TestClient:
        client = TestClient(app, base_url=base_url, headers=headers)
        clients.append(client)
        return client

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(httpx, "Client", client_factory)
        patch.setenv("METAIRL_API_KEY", api_key)
        try:
            for block in python:
                if "worker" in block.tags and not with_worker:
                    continue
                exec(compile("\n" * (block.line - 1) + block.code, block.path, "exec"), namespace)
        finally:
            for client in clients:
                client.close()
    assert clients, f"{python[0].path}: the first block must create `client` with httpx.Client(...)"
    return namespace


# ---------------------------------------------------------------- python blocks, without a worker


@pytest.mark.parametrize("path", EXECUTED)
def test_python_examples_run_up_to_the_worker(path: str, app: FastAPI, api_key: str) -> None:
    namespace = run_blocks(blocks(path, "python"), app, api_key, with_worker=False)
    assert isinstance(namespace.get("client"), TestClient)


def test_a_failing_example_fails_with_its_file_and_line(app: FastAPI, api_key: str) -> None:
    """The harness itself: a wrong example fails the test, and the traceback points into the doc."""
    setup = Block(
        "docs/fake.md", 3, (), "import httpx\nclient = httpx.Client(base_url='http://x', headers={})\n"
    )
    wrong = Block(
        "docs/fake.md", 9, (), "status = client.get('/healthz').status_code\nassert status == 418, status\n"
    )
    later = Block("docs/fake.md", 20, ("worker",), "raise SystemExit('never reached')\n")
    assert run_blocks([setup, later], app, api_key, with_worker=False)["client"]
    with pytest.raises(AssertionError, match="200") as info:
        run_blocks([setup, wrong], app, api_key, with_worker=False)
    entry = info.traceback[-1]
    assert (Path(entry.path).name, entry.lineno + 1) == ("fake.md", 10)


def test_the_notebook_page_runs_in_a_plain_python_session(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """docs/notebook.md uses the engine alone: its blocks run in order in one namespace, no app involved."""
    monkeypatch.chdir(tmp_path)  # the page saves a file
    namespace: dict[str, Any] = {}
    for block in blocks("docs/notebook.md", "python"):
        exec(compile("\n" * (block.line - 1) + block.code, block.path, "exec"), namespace)
    assert (tmp_path / "two-walks.npz").exists()


# ---------------------------------------------------------------- python blocks, with a real worker


@pytest.fixture(scope="module")
def worker_stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[FastAPI, str]]:
    """An app on the embedded backend (SQLite + filesystem broker) with one real worker; its API key."""
    from tests.jobs.conftest import FAST, Workers  # the jobs tests' worker launcher

    root = tmp_path_factory.mktemp("docs-worker")
    settings = Settings(
        data_dir=root / "var",
        queue_name=f"metairl-docs-{secrets.token_hex(4)}",
        **FAST,  # type: ignore[arg-type]
    )
    workers = Workers(settings, root)
    app = create_app(settings)
    try:
        with app.state.sessionmaker() as session:
            key = create_key(session, f"docs-{secrets.token_hex(3)}")
        workers.start()
        yield app, key
    finally:
        workers.kill_all()
        app.state.engine.dispose()


@pytest.mark.worker
@pytest.mark.slow
@pytest.mark.parametrize("path", EXECUTED)
def test_python_examples_run_with_a_worker(path: str, worker_stack: tuple[FastAPI, str]) -> None:
    app, key = worker_stack
    python = blocks(path, "python")
    assert any("worker" in b.tags for b in python), f"{path} has no worker blocks"
    run_blocks(python, app, key, with_worker=True)


# ---------------------------------------------------------------- curl lines against the OpenAPI

CURL_URL = re.compile(r"^(?:\$URL|\$\{URL\}|https?://[^/\s]+)(?P<path>/[^?#]*)")
METHOD_FLAGS = {"-X", "--request"}
BODY_FLAGS = {"-d", "--data", "--data-binary", "--data-raw", "--json", "-F", "--form", "-T"}


def shell_commands(text: str) -> list[list[str]]:
    """The simple commands of a shell script: logical lines (backslash continuations and multi-line
    quotes joined) split at ``|``, ``;``, ``&&``, ``||``, ``$(`` and ``)``; each a list of words."""
    commands: list[list[str]] = []
    pending = ""
    for line in text.replace("\\\n", " ").splitlines():
        pending += line + "\n"
        lexer = shlex.shlex(pending, posix=True, punctuation_chars=";&|()")
        lexer.whitespace_split = True
        try:
            tokens = list(lexer)
        except ValueError:  # an open quote: the command goes on on the next line
            continue
        pending = ""
        words: list[str] = []
        for token in [*tokens, ";"]:
            if token and set(token) <= set(";&|()"):
                if words:
                    commands.append(words)
                words = []
            else:
                words.append(token.removesuffix("$") if token.endswith("=$") else token)
    assert not pending, f"unterminated shell command: {pending!r}"
    return commands


def curl_commands(path: str) -> list[tuple[Block, list[str]]]:
    """Every curl command of a file's bash/sh blocks, with its block."""
    found = []
    for block in blocks(path, "bash") + blocks(path, "sh"):
        for words in shell_commands(block.code):
            if words[0] == "curl":
                found.append((block, words))
            elif "curl" in words:
                raise AssertionError(f"{block.where}: curl not at the start of a command: {words}")
    return found


def curl_request(argv: list[str]) -> tuple[str, str]:
    """(METHOD, path) of a curl argument list."""
    method, url = None, None
    body = False
    args = iter(argv[1:])
    for arg in args:
        if arg in METHOD_FLAGS:
            method = next(args)
        elif arg in BODY_FLAGS:
            body = True
            next(args)
        elif arg in {"-H", "--header", "-o", "--output", "-w"}:
            next(args)
        elif not arg.startswith("-"):
            url = arg
    assert url is not None, f"no URL in {argv}"
    match = CURL_URL.match(url)
    assert match, f"curl URL {url!r} must start with $URL or http(s)://host"
    return (method or ("POST" if body else "GET")).upper(), match["path"]


def route_pattern(template: str) -> re.Pattern[str]:
    """An OpenAPI path template as a regex: ``{param}`` matches one segment."""
    return re.compile("^" + re.sub(r"\\\{[^/]+?\\\}", "[^/]+", re.escape(template)) + "$")


def find_route(openapi: dict[str, Any], method: str, path: str) -> bool:
    """Whether the OpenAPI has an operation for ``method`` on a path template matching ``path``."""
    concrete = re.sub(r"\$\{?\w+\}?", "x", path).rstrip("/") or "/"
    return any(
        route_pattern(template).match(concrete) and method.lower() in operations
        for template, operations in openapi["paths"].items()
    )


@pytest.fixture(scope="module")
def openapi(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The app's OpenAPI document (an app on a throwaway SQLite database)."""
    app = create_app(Settings(data_dir=tmp_path_factory.mktemp("openapi")))
    try:
        document: dict[str, Any] = app.openapi()
        return document
    finally:
        app.state.engine.dispose()


@pytest.mark.parametrize("path", DOCUMENTED)
def test_every_curl_line_uses_an_existing_route(path: str, openapi: dict[str, Any]) -> None:
    commands = curl_commands(path)
    if path != "docs/architecture.md":
        assert commands, f"{path} has no curl examples"
    missing = [
        f"{block.where}: {method} {url_path}"
        for block, (method, url_path) in ((b, curl_request(argv)) for b, argv in commands)
        if not find_route(openapi, method, url_path)
    ]
    assert not missing, "curl examples use routes the app does not have:\n" + "\n".join(missing)


def test_curl_parser_rejects_unknown_routes(openapi: dict[str, Any]) -> None:
    argv = shlex.split('curl -s "$URL/v1/tasks/$TASK_ID/demonstrations" -H "$AUTH" -d @demos.json')
    assert curl_request(argv) == ("POST", "/v1/tasks/$TASK_ID/demonstrations")
    assert find_route(openapi, "POST", "/v1/tasks/$TASK_ID/demonstrations")
    assert not find_route(openapi, "DELETE", "/v1/tasks/$TASK_ID/demonstrations")
    assert not find_route(openapi, "GET", "/v1/nonsense/$ID")
    assert curl_request(shlex.split('curl -X PUT "$URL/v1/tasks/$T/true-reward" -d "{}"'))[0] == "PUT"
    script = 'A=$(curl -s "$URL/v1/mdps" -H "$AUTH" \\\n  -d \'{"a": [1,\n 2]}\' | jq -r .id)\necho "$A"; curl "$URL/healthz"\n'
    assert shell_commands(script) == [
        ["A="],
        ["curl", "-s", "$URL/v1/mdps", "-H", "$AUTH", "-d", '{"a": [1,\n 2]}'],
        ["jq", "-r", ".id"],
        ["echo", "$A"],
        ["curl", "$URL/healthz"],
    ]


# ---------------------------------------------------------------- configuration table

ROW = re.compile(r"^\|\s*`(METAIRL_[A-Z0-9_]+)`\s*\|\s*([^|]*?)\s*\|", re.M)


def documented_default(cell: str) -> Any:
    """The default a table cell states: ``(unset)`` is None, a backticked value is its text."""
    if cell == "(unset)":
        return None
    match = re.fullmatch(r"`([^`]*)`", cell)
    assert match, f"default cell {cell!r} must be `value` or (unset)"
    return match[1]


def test_every_setting_is_in_the_readme_table_with_its_default() -> None:
    rows = dict(ROW.findall((REPO / "README.md").read_text(encoding="utf-8")))
    defaults = Settings.model_fields
    for name, field in defaults.items():
        variable = f"METAIRL_{name.upper()}"
        assert variable in rows, f"README's configuration table lacks {variable}"
        stated = documented_default(rows[variable])
        default = field.default
        if default is None:
            assert stated is None, f"{variable}: README says {stated!r}, the default is unset"
        elif isinstance(default, bool):
            assert stated in {"true", "false"} and (stated == "true") == default, (
                f"{variable}: README says {stated!r}, default {default!r}"
            )
        elif isinstance(default, Path):
            assert Path(stated) == default, f"{variable}: README says {stated!r}, the default is {default}"
        else:
            assert type(default)(stated) == default, (
                f"{variable}: README says {stated!r}, default {default!r}"
            )
    extra = set(rows) - {f"METAIRL_{n.upper()}" for n in defaults}
    assert not extra, f"README's table has rows for variables that are not settings: {extra}"


@pytest.mark.parametrize("path", DOCUMENTED)
def test_every_metairl_variable_named_in_the_docs_exists(path: str) -> None:
    named = set(re.findall(r"METAIRL_[A-Z0-9_]*[A-Z0-9]", (REPO / path).read_text(encoding="utf-8")))
    known = {f"METAIRL_{n.upper()}" for n in Settings.model_fields} | EXTRA_VARIABLES
    assert not named - known, f"{path} names variables no code reads: {named - known}"


# ---------------------------------------------------------------- links

LINK = re.compile(r"\]\((?!https?://|#|mailto:)([^)\s#]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("path", PAGES)
def test_relative_links_point_at_files(path: str) -> None:
    base = (REPO / path).parent
    text = (REPO / path).read_text(encoding="utf-8")
    broken = [target for target in LINK.findall(text) if not (base / target).exists()]
    assert not broken, f"{path} links to missing files: {sorted(broken)}"


def test_docs_hold_no_absolute_machine_paths() -> None:
    for path in [*PAGES, *(str(p.relative_to(REPO)) for p in (REPO / "docs/examples").glob("*.py"))]:
        text = (REPO / path).read_text(encoding="utf-8")
        found = re.findall(r"(?<![\w.])/(?:work|tmp|root|home)/\S+", text)
        assert not found, f"{path} names absolute machine paths {found}"


# ---------------------------------------------------------------- job config table

CONFIG_ROW = re.compile(r"^\|\s*`([a-z_]+)`\s*\|\s*`([^`]*)`\s*\|", re.M)


def test_every_job_config_field_is_in_the_api_guide_with_its_default() -> None:
    from metairl_engine.config import FitConfig

    text = (REPO / "docs/api.md").read_text(encoding="utf-8")
    rows = {name: json.loads(default) for name, default in CONFIG_ROW.findall(text)}
    assert rows == FitConfig().to_dict(), "docs/api.md's config table differs from FitConfig's defaults"


# ---------------------------------------------------------------- the README's curl walk-through, for real


@pytest.mark.worker
@pytest.mark.slow
def test_the_readme_curl_block_runs_against_metairl_serve(tmp_path: Path) -> None:
    """README's curl quickstart, as a bash script with ``set -e``, against a real `metairl serve` (API and
    worker): it must reach a succeeded job and save a real PNG."""
    from tests.served import metairl_serve

    (script,) = [b for b in blocks("README.md", "bash") if "/v1/jobs" in b.code]
    with metairl_serve(tmp_path) as served:
        done = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", script.code],
            cwd=tmp_path,
            env={**os.environ, "URL": served.url, "METAIRL_API_KEY": served.key},
            capture_output=True,
            text=True,
            timeout=300,
        )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "succeeded" in done.stdout
    assert (tmp_path / "baseline.png").read_bytes().startswith(b"\x89PNG")
