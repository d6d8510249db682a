"""The OpenAPI document describes every endpoint: tags, summary, and examples of JSON bodies in and out."""

from __future__ import annotations

import json
import re
from typing import Any

from fastapi import FastAPI

BINARY = ("application/octet-stream", "image/png", "text/csv")


def has_example(schema: dict[str, Any], schemas: dict[str, Any]) -> bool:
    """Whether a schema (following one $ref, and a list page's items) carries an example."""
    if "$ref" in schema:
        schema = schemas[schema["$ref"].rsplit("/", 1)[1]]
    if "examples" in schema or "example" in schema:
        return True
    data = schema.get("properties", {}).get("data")
    return data is not None and has_example(data.get("items", {}), schemas)


def test_every_operation_has_tags_summary_and_examples(app: FastAPI) -> None:
    document = app.openapi()
    schemas = document["components"]["schemas"]
    missing = []
    for path, item in document["paths"].items():
        for method, operation in item.items():
            where = f"{method.upper()} {path}"
            if not operation.get("tags") or not operation.get("summary"):
                missing.append(f"{where}: tags/summary")
            body = operation.get("requestBody", {}).get("content", {}).get("application/json")
            if body is not None and not ("examples" in body or has_example(body["schema"], schemas)):
                missing.append(f"{where}: request example")
            for status, response in operation["responses"].items():
                for media, content in response.get("content", {}).items():
                    documented = "example" in content or has_example(content.get("schema", {}), schemas)
                    if status.startswith("2") and media not in BINARY and not documented:
                        missing.append(f"{where}: {status} {media} example")
    assert missing == []


def test_every_schema_reference_resolves(app: FastAPI) -> None:
    document = app.openapi()
    referenced = set(re.findall(r"#/components/schemas/([^\"]+)", json.dumps(document)))
    assert referenced <= set(document["components"]["schemas"])


def test_uploads_are_documented_as_multipart(app: FastAPI) -> None:
    paths = app.openapi()["paths"]
    for path in ("/v1/mdps", "/v1/tasks/{task_id}/demonstrations"):
        content = paths[path]["post"]["requestBody"]["content"]
        assert {"application/json", "multipart/form-data"} <= set(content)


def test_the_job_config_schema_documents_every_fit_setting(app: FastAPI) -> None:
    """Each `FitConfig` field is in the schema with its docstring, its default and (where it has one) its range."""
    from dataclasses import fields

    from metairl_engine.config import FitConfig

    properties = app.openapi()["components"]["schemas"]["JobConfig"]["properties"]
    defaults = FitConfig().to_dict()
    assert set(properties) == set(defaults)
    for f in fields(FitConfig):
        schema = properties[f.name]
        assert schema.get("description"), f.name
        assert schema.get("default") == defaults[f.name], f.name  # null defaults are left out
    assert (properties["max_steps"]["minimum"], properties["max_steps"]["maximum"]) == (1, 100_000)
    assert properties["holdout_fraction"]["exclusiveMaximum"] == 1


def test_a_job_submission_is_documented_with_its_config_schema(app: FastAPI) -> None:
    """The route checks the body itself (every problem in one 422); the schema still says what it takes."""
    document = app.openapi()
    body = document["paths"]["/v1/jobs"]["post"]["requestBody"]
    assert body["required"] and body["content"]["application/json"]["schema"] == {
        "$ref": "#/components/schemas/JobIn"
    }
    job_in = document["components"]["schemas"]["JobIn"]
    assert (job_in["required"], job_in["additionalProperties"]) == (["demonstrator_id"], False)
    assert job_in["properties"]["config"]["anyOf"] == [
        {"$ref": "#/components/schemas/JobConfig"},
        {"type": "null"},
    ]
