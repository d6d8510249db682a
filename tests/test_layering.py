"""The import rules between our packages, read from the source with `ast` (docs/architecture.md):

- `metairl_engine` imports nothing of ours;
- `service` imports `metairl_engine` only, and only its numpy-only modules (never one that imports torch);
- `worker` imports `service` and `metairl_engine`;
- `metairl_client` imports nothing of ours (httpx, httpx-sse, numpy, tqdm and the standard library only);
- `metairl_cli` may import anything; nothing of ours imports it;
- the API process (everything `service.api.app` imports, transitively) never imports torch;
- inside `service`, rooms stacked bottom to top (`SERVICE_LAYERS`): a module imports only its own room and
  the rooms below it, so nothing imports `service.api` but the API itself, and the store imports nothing above it.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from functools import cache
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
OURS = ("metairl_engine", "service", "worker", "metairl_client", "metairl_cli")
ALLOWED: dict[str, set[str]] = {
    "metairl_engine": {"metairl_engine"},
    "service": {"service", "metairl_engine"},
    "worker": {"worker", "service", "metairl_engine"},
    "metairl_client": {"metairl_client"},
    "metairl_cli": set(OURS),
}
CLIENT_THIRD_PARTY = {"httpx", "httpx_sse", "numpy", "tqdm"}
# Inside `service`, bottom to top; a module belongs to the room of its longest matching prefix.
SERVICE_LAYERS = (
    ("service", "service.settings", "service.problems", "service.sizes"),
    ("service.store.models",),
    ("service.domain",),
    ("service.files",),
    ("service.store",),
    ("service.jobs",),
    ("service.results",),
    ("service.api",),
)


def module_files() -> dict[str, Path]:
    """Every module of our packages, by dotted name."""
    found = {}
    for package in OURS:
        for path in sorted((REPO / package).rglob("*.py")):
            parts = path.relative_to(REPO).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found[name] = path
    return found


MODULES = module_files()


@cache
def imports_of(module: str) -> frozenset[str]:
    """The absolute names a module imports (module-level or inside functions), ``from x import y`` as ``x.y``
    when ``x.y`` is a module of ours, else ``x``."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            names.add(base)
            names |= {f"{base}.{alias.name}" for alias in node.names if f"{base}.{alias.name}" in MODULES}
    return frozenset(names)


def ours(name: str) -> str | None:
    """The module of ours that ``name`` is or lies in (its longest known prefix), or None."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        candidate = ".".join(parts[:end])
        if candidate in MODULES:
            return candidate
    return None


def transitive(module: str) -> set[str]:
    """Our modules that importing ``module`` loads (packages' ``__init__`` included)."""
    seen: set[str] = set()
    todo = [module]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        parts = current.split(".")
        todo += [".".join(parts[:end]) for end in range(1, len(parts)) if ".".join(parts[:end]) in MODULES]
        todo += [m for m in (ours(n) for n in imports_of(current)) if m is not None]
    return seen


def imports_torch(module: str) -> bool:
    """Whether the module itself imports torch."""
    return any(n == "torch" or n.startswith("torch.") for n in imports_of(module))


TORCH_ENGINE = {m for m in MODULES if m.startswith("metairl_engine") and imports_torch(m)}


def test_the_graph_sees_every_package_and_the_torch_modules() -> None:
    assert {m.split(".")[0] for m in MODULES} == set(OURS)
    assert "metairl_engine.fit" in TORCH_ENGINE and "metairl_engine.mdp" not in TORCH_ENGINE


@pytest.mark.parametrize("package", OURS)
def test_each_package_imports_only_what_its_layer_allows(package: str) -> None:
    broken = sorted(
        f"{module} imports {name}"
        for module in MODULES
        if module.split(".")[0] == package
        for name in imports_of(module)
        if name.split(".")[0] in OURS and name.split(".")[0] not in ALLOWED[package]
    )
    assert not broken, "\n".join(broken)


def service_layer(module: str) -> int:
    """The height of the service room ``module`` lies in (its longest matching prefix in `SERVICE_LAYERS`)."""
    matches = [
        (len(prefix), height)
        for height, prefixes in enumerate(SERVICE_LAYERS)
        for prefix in prefixes
        if module == prefix or module.startswith(prefix + ".")
    ]
    return max(matches)[1]


def test_service_rooms_import_only_downwards() -> None:
    broken = sorted(
        f"{module} imports {name} (above it)"
        for module in MODULES
        if module.startswith("service.")
        for name in imports_of(module)
        if (target := ours(name)) is not None
        and target.startswith("service.")
        and service_layer(target) > service_layer(module)
    )
    assert not broken, "\n".join(broken)


def test_service_uses_only_numpy_only_engine_modules() -> None:
    broken = sorted(
        f"{module} loads {dep}"
        for module in MODULES
        if module.split(".")[0] == "service"
        for dep in transitive(module)
        if dep in TORCH_ENGINE
    )
    assert not broken, "\n".join(broken)


def test_the_client_needs_only_its_declared_libraries_and_the_standard_library() -> None:
    broken = sorted(
        f"{module} imports {name}"
        for module in MODULES
        if module.startswith("metairl_client")
        for name in imports_of(module)
        if name.split(".")[0] not in {"metairl_client", *CLIENT_THIRD_PARTY}
        and name.split(".")[0] not in sys.stdlib_module_names
        and name != "__future__"
    )
    assert not broken, "\n".join(broken)


def test_the_api_process_never_imports_torch() -> None:
    loaded = transitive("service.api.app")
    assert not any(imports_torch(m) for m in loaded), sorted(m for m in loaded if imports_torch(m))
    assert not any(m.startswith(("worker", "metairl_cli", "metairl_client")) for m in loaded)
    # ezc3d too: C3D files are read in a child process (service/files/c3d.py), never in the API's own.
    code = "import sys, service.api.app; print(sorted(m for m in ('torch', 'worker', 'ezc3d') if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_a_broken_rule_is_caught(tmp_path: Path) -> None:
    """The checker itself: a service module importing the worker or a torch module is reported."""
    MODULES["service.zz_bad"] = bad = tmp_path / "zz_bad.py"
    try:
        bad.write_text("import worker.tasks\nfrom metairl_engine.fit import fit\n")
        imports_of.cache_clear()
        with pytest.raises(AssertionError, match=re.escape("service.zz_bad imports worker.tasks")):
            test_each_package_imports_only_what_its_layer_allows("service")
        with pytest.raises(AssertionError, match=re.escape("service.zz_bad loads metairl_engine.fit")):
            test_service_uses_only_numpy_only_engine_modules()
    finally:
        del MODULES["service.zz_bad"]
        imports_of.cache_clear()


@pytest.mark.parametrize(
    ("module", "imported"),
    [("service.store.zz_bad", "service.jobs.transitions"), ("service.files.zz_bad", "service.store.blobs")],
)
def test_an_upward_import_inside_service_is_caught(tmp_path: Path, module: str, imported: str) -> None:
    """The room checker itself: the store importing the job lifecycle, or the files importing the store, is reported."""
    MODULES[module] = bad = tmp_path / "zz_bad.py"
    try:
        bad.write_text(f"import {imported}\n")
        imports_of.cache_clear()
        with pytest.raises(AssertionError, match=re.escape(f"{module} imports {imported} (above it)")):
            test_service_rooms_import_only_downwards()
    finally:
        del MODULES[module]
        imports_of.cache_clear()
