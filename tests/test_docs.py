"""The documentation's examples are executed, so they cannot rot.

- Python: the fenced blocks marked ``python`` in README.md, docs/api.md and docs/client.md run in order, in one namespace
  per file, against the in-process app (``httpx.Client`` is swapped for FastAPI's TestClient, which takes
  the same ``base_url`` and ``headers``). Blocks marked ``python worker`` need a job to finish: the first
  test stops before them, a second (``@pytest.mark.worker``) runs every block with a real worker process.
- Shell: every ``curl`` line's path and method must exist in the app's OpenAPI. Every ``bash``/``sh`` block of
  README.md and docs/*.md runs too, each page's in order in one ``bash -euo pipefail`` shell against one real
  `metairl serve`: each answer of 400 and over must be named in its block (``# 422``), each named status must
  occur, files saved with ``-o`` must be what their suffix says. A block tagged ``no-run`` may hold only the
  allow-listed commands of `NOT_RUN` (starting the service, installing, long experiments tested elsewhere).
- Configuration: every `Settings` field is a row ``METAIRL_<NAME>`` of README's table, with its default;
  every ``METAIRL_*`` the docs mention is a setting (or a documented extra).
- Relative links in README and docs/ point at files that exist.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import secrets
import shlex
import subprocess
import sys
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
from tests.served import Served, metairl_serve

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
        elif arg in {
            "-H",
            "--header",
            "-o",
            "--output",
            "-w",
            "-D",
            "--dump-header",
            "--etag-save",
            "--etag-compare",
        }:
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


CONFIG_RANGE = re.compile(r"^\|\s*`([a-z_]+)`\s*\|\s*`[^`]*`\s*\|([^|]*)\|", re.M)


def documented_number(value: int | float) -> str:
    """How the config table writes a bound: thousands separated, and 2^k − 1 for a large power of two less one."""
    if isinstance(value, int) and value >= 2**32 and (value + 1).bit_count() == 1:
        return f"2^{(value + 1).bit_length() - 1} − 1"
    return f"{value:,}"


SCHEMA_BOUNDS = {"minimum": "≥", "exclusiveMinimum": ">", "maximum": "≤", "exclusiveMaximum": "<"}
"""The JSON schema's bounds, lower first, and how the config table writes each."""


def documented_range(schema: dict[str, Any]) -> str:
    """A setting's range as the config table writes it from its JSON schema: ``1 – 100,000`` where both ends are
    accepted, else its bounds (``> 0, ≤ 1``); empty without bounds."""
    bounds = [(sign, schema[key]) for key, sign in SCHEMA_BOUNDS.items() if key in schema]
    if [sign for sign, _ in bounds] == ["≥", "≤"]:
        return f"{documented_number(bounds[0][1])} – {documented_number(bounds[1][1])}"
    return ", ".join(f"{sign} {documented_number(limit)}" for sign, limit in bounds)


def test_every_job_config_setting_is_in_the_api_guide_with_its_range() -> None:
    from service.domain.job_config import JobConfig

    text = (REPO / "docs/api.md").read_text(encoding="utf-8")
    documented = {name: cell.strip() for name, cell in CONFIG_RANGE.findall(text)}
    schema = {name: documented_range(p) for name, p in JobConfig.model_json_schema()["properties"].items()}
    assert documented == schema, "docs/api.md's config table differs from the job config schema's ranges"


# ---------------------------------------------------------------- shell blocks, run against metairl serve

NO_RUN = "no-run"
"""Info-string tag of a shell block the test does not run (only the commands of `NOT_RUN` may be in one)."""
NOT_RUN: dict[tuple[str, ...], str] = {
    ("bash", "scripts/serve.sh"): "starts the service; the test runs the blocks against its own",
    ("bash", "scripts/test.sh"): "the whole test suite",
    ("pip", "install"): "installs into the reader's environment",
    (".venv/bin/metairl", "demo"): "18 to 250 jobs; tests/test_demo.py runs --quick against metairl serve",
    ("python", "-m", "benchmarks.reliability"): "a benchmark that starts its own service, about 35 s",
    (".venv/bin/python", "docs/examples/motion_tutorial.py", "run"): (
        "two fits of minutes; tests/test_motion_tutorial.py runs the script end to end on a 12×12 grid"
    ),
}
"""The only kinds of command a ``no-run`` block may hold (a prefix of its words), and why each is not run."""
SHELL_PAGES = ("README.md", *sorted(f"docs/{page.name}" for page in (REPO / "docs").glob("*.md")))
"""Every page whose ``bash``/``sh`` blocks are run (README.md and docs/*.md)."""
HARNESS = r"""docs_block=-1
curl() {  # the real curl; also writes "<block> <HTTP status of its last answer>" to $DOCS_CURL_LOG
  local headers rc=0
  headers=$(mktemp)
  command curl -D "$headers" "$@" || rc=$?
  printf '%s %s\n' "$docs_block" "$(tr -d '\r' < "$headers" | awk '/^HTTP\// {code = $2} END {print code}')" \
    >> "$DOCS_CURL_LOG"
  rm -f "$headers"
  return "$rc"
}
trap 'echo "docs-failed $docs_block $LINENO" >&2' ERR
"""
"""Prepended to a page's blocks: logs each answer's status per block, and says where the script stopped."""
NAMED_STATUS = re.compile(r"#\s*([1-5]\d\d)\b")
"""A comment that says what a request answers: ``# 422``, ``# 204 once unused``."""
MAGIC = {".png": b"\x89PNG", ".npy": b"\x93NUMPY", ".npz": b"PK"}
"""First bytes of the files the blocks save, by suffix."""


def shell_blocks(path: str) -> list[Block]:
    """A page's ``bash`` and ``sh`` blocks, in page order."""
    return sorted(blocks(path, "bash") + blocks(path, "sh"), key=lambda block: block.line)


def runnable(path: str) -> list[Block]:
    """The shell blocks of a page that the test runs."""
    return [block for block in shell_blocks(path) if NO_RUN not in block.tags]


@dataclass(frozen=True)
class ShellRun:
    """A page's blocks run as one script: exit code, output, each request's (block index, status), folder."""

    returncode: int
    stdout: str
    stderr: str
    answers: list[tuple[int, str]]
    folder: Path


def run_shell_blocks(
    page: list[Block], served: Served, folder: Path, *, env: dict[str, str], timeout_s: float = 300
) -> ShellRun:
    """Run blocks in order as one ``bash -euo pipefail`` script in ``folder`` (as a reader pastes them into one
    shell) against ``served``: ``URL`` and ``METAIRL_API_KEY`` set, the Python environment's bin first on PATH."""
    script = HARNESS + "".join(f"docs_block={i}\n{block.code}\n" for i, block in enumerate(page))
    (folder / "docs.sh").write_text(script, encoding="utf-8")
    log = folder / "curl.log"
    log.write_text("")
    done = subprocess.run(
        ["bash", "-euo", "pipefail", "docs.sh"],
        cwd=folder,
        env=env
        | {
            "URL": served.url,
            "METAIRL_API_KEY": served.key,
            "DOCS_CURL_LOG": str(log),
            "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
        },
        capture_output=True,
        text=True,
        timeout=timeout_s,
    )
    answers = [
        (int(block), status)
        for block, _, status in (line.partition(" ") for line in log.read_text().splitlines())
    ]
    return ShellRun(done.returncode, done.stdout, done.stderr, answers, folder)


def shell_failures(page: list[Block], run: ShellRun) -> list[str]:
    """What went wrong, each naming its block: the block the script stopped in (and the page line near where),
    answers of 400 and over its block does not name with ``# <status>``, named statuses nothing answered,
    and saved files whose first bytes do not match their suffix."""
    failures = []
    if run.returncode != 0:
        stopped = re.findall(r"^docs-failed (-?\d+) (\d+)$", run.stderr, re.M)
        where = "the harness"
        if stopped and int(stopped[0][0]) >= 0:
            index, script_line = int(stopped[0][0]), int(stopped[0][1])
            block = page[index]
            start = HARNESS.count("\n") + sum(b.code.count("\n") + 2 for b in page[:index]) + 2
            where = f"{block.where} (near {block.path}:{block.line + script_line - start})"
        tail = (run.stdout[-3000:] + "\n" + run.stderr[-3000:]).strip()
        failures.append(f"{where}: exit {run.returncode}\n{tail}")
    for index, block in enumerate(page):
        answered = [status for i, status in run.answers if i == index]
        named = set(NAMED_STATUS.findall(block.code))
        unnamed = [s for s in answered if (not s or int(s) >= 400) and s not in named]
        if unnamed:
            failures.append(
                f"{block.where}: answers {unnamed} that the block does not name with `# <status>`"
            )
        if named - set(answered):
            failures.append(f"{block.where}: names {sorted(named - set(answered))}, answered {answered}")
        for words in shell_commands(block.code):
            saved = next((words[i + 1] for i, w in enumerate(words[:-1]) if w in {"-o", "--output"}), None)
            if words[0] == "curl" and saved and saved != "/dev/null" and run.returncode == 0:
                magic = MAGIC.get(Path(saved).suffix, b"")
                if (
                    not (run.folder / saved).read_bytes().startswith(magic)
                    or not (run.folder / saved).stat().st_size
                ):
                    failures.append(f"{block.where}: {saved} is not a {Path(saved).suffix} file")
    return failures


@pytest.fixture(scope="module")
def docs_served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Served, dict[str, str]]]:
    """One `metairl serve` (API and one worker) for every page's shell blocks; and the environment the blocks
    run in (this process's, with the server's ``METAIRL_*`` settings, so `metairl keys` finds its database)."""
    folder = tmp_path_factory.mktemp("docs-serve")
    with metairl_serve(folder) as served:
        env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
        yield served, env | {"METAIRL_DATA_DIR": str(folder / "var")}


def page_folder(tmp_path: Path) -> Path:
    """An empty folder to run a page in, where ``docs/`` and ``.venv/`` lead to the repo's, as from a clone."""
    (tmp_path / "docs").symlink_to(REPO / "docs")
    (tmp_path / ".venv").symlink_to(Path(sys.prefix))
    return tmp_path


@pytest.mark.worker
@pytest.mark.slow
@pytest.mark.parametrize("path", [p for p in SHELL_PAGES if runnable(p)])
def test_shell_blocks_run_in_order_against_metairl_serve(
    path: str, docs_served: tuple[Served, dict[str, str]], tmp_path: Path
) -> None:
    """Every shell block of the page not marked ``no-run``, in order, in one shell, against a real `metairl
    serve`: it must exit 0, every answer of 400 and over must be one its block names, every status a block
    names must be answered, and every file saved with ``-o`` must be what its suffix says."""
    served, env = docs_served
    page = runnable(path)
    run = run_shell_blocks(page, served, page_folder(tmp_path), env=env)
    failures = shell_failures(page, run)
    assert not failures, "\n".join(failures)
    assert len(run.answers) >= sum(words[0] == "curl" for b in page for words in shell_commands(b.code))


@pytest.mark.worker
@pytest.mark.slow
def test_a_failing_shell_block_fails_naming_its_file_and_line(
    docs_served: tuple[Served, dict[str, str]], tmp_path: Path
) -> None:
    """The harness itself: a failing command names its block and line; an unnamed 401 fails, a named one
    passes; a named status nothing answered fails."""
    served, env = docs_served
    first = Block("docs/fake.md", 3, (), 'AUTH="Authorization: Bearer $METAIRL_API_KEY"\n')
    failing = Block("docs/fake.md", 9, (), 'curl -s "$URL/healthz"\n\nfalse\necho never\n')
    run = run_shell_blocks([first, failing], served, tmp_path, env=env)
    assert shell_failures([first, failing], run)[0].startswith(
        "docs/fake.md:9 (near docs/fake.md:11): exit 1"
    )
    unnamed = Block("docs/fake.md", 9, (), 'curl -s "$URL/v1/mdps"\n')
    named = Block("docs/fake.md", 9, (), 'curl -s "$URL/v1/mdps"  # 401: no key\n')
    wrong = Block("docs/fake.md", 9, (), 'curl -s "$URL/v1/mdps" -H "$AUTH"  # 401\n')
    assert (
        "answers ['401']"
        in shell_failures([first, unnamed], run_shell_blocks([first, unnamed], served, tmp_path, env=env))[0]
    )
    assert shell_failures([first, named], run_shell_blocks([first, named], served, tmp_path, env=env)) == []
    assert (
        "names ['401'], answered ['200']"
        in shell_failures([first, wrong], run_shell_blocks([first, wrong], served, tmp_path, env=env))[0]
    )


@pytest.mark.parametrize("path", SHELL_PAGES)
def test_shell_blocks_not_run_hold_only_allow_listed_commands(path: str) -> None:
    for block in shell_blocks(path):
        assert set(block.tags) <= {NO_RUN}, f"{block.where}: unknown shell block tags {block.tags}"
        if NO_RUN in block.tags:
            commands = shell_commands(block.code)
            assert commands, f"{block.where}: an empty no-run block"
            for words in commands:
                assert any(tuple(words[: len(kind)]) == kind for kind in NOT_RUN), (
                    f"{block.where}: `{' '.join(words)}` is not a command that may go unrun ({list(NOT_RUN)})"
                )


@pytest.mark.parametrize("path", SHELL_PAGES)
def test_shell_blocks_send_the_one_key_variable_and_fail_rather_than_save_a_problem(path: str) -> None:
    """``Bearer $METAIRL_API_KEY`` is the only key the blocks send, and a curl that saves its answer to a file
    has ``--fail`` (``-f``), so a problem+json is never saved as a picture or an array."""
    for block in runnable(path):
        keys = set(re.findall(r"Bearer \$\{?(\w+)", block.code))
        assert keys <= {"METAIRL_API_KEY"}, f"{block.where}: sends keys {keys}"
        for words in shell_commands(block.code):
            saves = any(w in {"-o", "--output"} and n != "/dev/null" for w, n in itertools.pairwise(words))
            fails = "--fail" in words or any(re.fullmatch(r"-[a-zA-Z]*f[a-zA-Z]*", w) for w in words)
            assert words[0] != "curl" or not saves or fails, (
                f"{block.where}: {' '.join(words)} saves without --fail"
            )
