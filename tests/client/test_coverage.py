"""Every operation of the live OpenAPI document has a client method, sync and async alike."""

from __future__ import annotations

import inspect
from pathlib import Path

from fastapi import FastAPI

from metairl_client import AsyncClient, Client
from tests.client.operations import NOT_OPERATIONS, OPERATION_METHODS, missing_operations, operations


def public_methods(cls: type) -> set[str]:
    """The public methods of a client class."""
    return {name for name, value in vars(cls).items() if callable(value) and not name.startswith("_")} | {
        name
        for name, value in vars(cls).items()
        if isinstance(value, classmethod) and not name.startswith("_")
    }


def test_every_api_operation_has_a_client_method(app: FastAPI) -> None:
    missing = missing_operations(app.openapi())
    assert not missing, (
        f"{len(missing)} API operation(s) have no client method; add one to metairl_client "
        "(both Client and AsyncClient) and to OPERATION_METHODS in tests/client/operations.py:\n  "
        + "\n  ".join(missing)
    )


def test_the_mapping_names_only_operations_the_api_has(app: FastAPI) -> None:
    stale = sorted(set(OPERATION_METHODS) - set(operations(app.openapi())))
    assert not stale, f"OPERATION_METHODS names operations the API no longer has: {stale}"


def test_every_mapped_method_exists_on_both_clients_and_every_method_is_mapped() -> None:
    mapped = {name for names in OPERATION_METHODS.values() for name in names}
    for cls in (Client, AsyncClient):
        assert mapped - public_methods(cls) == set(), cls.__name__
        assert public_methods(cls) - mapped - NOT_OPERATIONS == set(), cls.__name__


def test_the_async_client_has_the_sync_clients_signatures() -> None:
    def shape(cls: type, name: str) -> list[tuple[str, object, object]]:
        signature = inspect.signature(getattr(cls, name))
        return [(p.name, p.kind, p.default) for p in signature.parameters.values()]

    for name in public_methods(Client):
        assert shape(AsyncClient, name) == shape(Client, name), name
        is_iterator = name.startswith("iter_")
        assert inspect.iscoroutinefunction(getattr(AsyncClient, name)) == (
            not is_iterator and name not in {"connect", "with_options"}
        ), name


def test_the_client_guide_lists_every_method() -> None:
    guide = (Path(__file__).resolve().parents[2] / "docs" / "client.md").read_text()
    table = guide.split("## Every method", 1)[1].split("\n## ", 1)[0]
    mapped = {name for names in OPERATION_METHODS.values() for name in names}
    assert {name for name in mapped if f"`{name}`" not in table} == set()
