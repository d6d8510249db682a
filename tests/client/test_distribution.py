"""`metairl_client/` builds as its own wheel: its modules and ``py.typed``, needing only its four libraries."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from email.parser import Parser
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CLIENT = REPO / "metairl_client"


@pytest.mark.slow
def test_the_client_builds_as_a_wheel_with_its_types_and_only_its_libraries(tmp_path: Path) -> None:
    source = tmp_path / "metairl_client"
    shutil.copytree(CLIENT, source, ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            str(source),
            "-w",
            str(tmp_path),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("metairl_client-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        metadata = Parser().parsestr(archive.read(next(n for n in names if n.endswith("/METADATA"))).decode())
    modules = {f"metairl_client/{path.name}" for path in CLIENT.glob("*.py")}
    assert modules | {"metairl_client/py.typed"} <= names
    assert not any(name.endswith("pyproject.toml") for name in names)
    requirements = {
        line.split(">")[0].split("=")[0].strip() for line in metadata.get_all("Requires-Dist", [])
    }
    assert requirements == {"httpx", "httpx-sse", "numpy", "tqdm"}


def test_importing_the_client_loads_none_of_the_server() -> None:
    code = (
        "import sys, metairl_client; "
        "print(sorted(m for m in ('torch', 'fastapi', 'sqlalchemy', 'celery', 'service', 'metairl_engine') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
