"""Tenancy: for every `/v1` route (taken from the app's OpenAPI document, so none can be forgotten), another
lab gets 404 on lab A's resources, and lists without path parameters show only the caller's resources."""

from __future__ import annotations

import re
from typing import Any

from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.service.helpers import owned_resource_ids

PARAM = re.compile(r"\{(\w+)\}")


def v1_operations(app: FastAPI) -> list[tuple[str, str, dict[str, Any]]]:
    """(method, path template, operation) of every documented `/v1` route."""
    return [
        (method.upper(), path, operation)
        for path, item in app.openapi()["paths"].items()
        if path.startswith("/v1/")
        for method, operation in item.items()
    ]


def example_body(operation: dict[str, Any], schemas: dict[str, Any]) -> Any:
    """The first documented JSON example of an operation's body (a valid body), or None without a body."""
    content = operation.get("requestBody", {}).get("content", {}).get("application/json")
    if content is None:
        return None
    if "examples" in content:
        return next(iter(content["examples"].values()))["value"]
    schema = content["schema"]
    if "$ref" in schema:
        schema = schemas[schema["$ref"].rsplit("/", 1)[1]]
    return schema.get("examples", [{}])[0]


def test_every_route_with_a_path_parameter_hides_other_labs_resources(
    app: FastAPI, client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    ids = owned_resource_ids(app, client, auth)
    schemas = app.openapi()["components"]["schemas"]
    checked = []
    for method, template, operation in v1_operations(app):
        params = PARAM.findall(template)
        if not params:
            continue
        missing = [p for p in params if p not in ids]
        assert not missing, f"add a factory for {missing} to owned_resource_ids ({method} {template})"
        path = PARAM.sub(lambda m: ids[m.group(1)], template)
        body = example_body(operation, schemas)
        response = client.request(method, path, json=body, headers=auth_b)
        assert response.status_code == 404, (method, template, response.status_code, response.text)
        assert response.headers["content-type"].startswith("application/problem+json")
        if method == "GET":
            assert client.get(path, headers=auth).status_code != 404, (
                template,
                "lab A must see its own resource",
            )
        checked.append((method, template))
    assert ("GET", "/v1/tasks/{task_id}") in checked and (
        "POST",
        "/v1/demonstrators/{demonstrator_id}/tasks",
    ) in checked


def test_every_list_without_path_parameters_shows_only_own_resources(
    app: FastAPI, client: TestClient, auth: dict[str, str], auth_b: dict[str, str]
) -> None:
    own_a = set(owned_resource_ids(app, client, auth).values())
    owned_resource_ids(app, client, auth_b)
    lists = [t for m, t, _ in v1_operations(app) if m == "GET" and not PARAM.search(t)]
    assert "/v1/mdps" in lists and "/v1/demonstrators" in lists
    for template in lists:
        seen = {item["id"] for item in client.get(template, headers=auth_b).json()["data"]}
        assert seen, template
        assert not seen & own_a, (template, seen & own_a)
