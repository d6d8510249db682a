"""Contract gaps found by fuzzing, one test each: bodies, names, integers, media types,
malformed and non-UTF-8 JSON, empty cursors, 405 `Allow`, true rewards that do not fit float32, numbers given as
booleans or strings.
(Huge finite correlations: `test_comparisons.py`; CSV rows with extra cells: `test_demonstrations.py`.)"""

from __future__ import annotations

from typing import Any

import pytest
from fastapi import FastAPI
from fastapi.testclient import TestClient

from tests.service.helpers import make_demonstrator, make_task

JSON = {"Content-Type": "application/json"}


def problem(response: Any, status: int) -> dict[str, Any]:
    """The problem+json body of a response that must have `status`."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/problem+json")
    body: dict[str, Any] = response.json()
    return body


def test_a_true_reward_that_does_not_fit_float32_is_422(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    body = problem(
        client.put(f"/v1/tasks/{task['id']}/true-reward", json={"values": [0, 1e300, 0]}, headers=auth), 422
    )
    assert body["errors"][0]["pointer"] == "/values/1" and "float32" in body["errors"][0]["message"]
    assert client.get(f"/v1/tasks/{task['id']}/true-reward", headers=auth).status_code == 404


@pytest.mark.parametrize("value", [True, "1.5"])
def test_a_number_given_as_a_boolean_or_a_string_is_422_naming_it(
    client: TestClient, auth: dict[str, str], value: Any
) -> None:
    task = make_task(client, auth)
    reward = client.put(f"/v1/tasks/{task['id']}/true-reward", json={"values": [0, value, 1]}, headers=auth)
    assert problem(reward, 422)["errors"][0]["pointer"] == "/values/1"
    grid = {"kind": "grid", "name": "g", "width": 3, "height": 3, "gamma": 0.9, "slip": value}
    assert problem(client.post("/v1/mdps", json=grid, headers=auth), 422)["errors"][0]["pointer"] == "/slip"


@pytest.mark.parametrize("name", ["   ", "\t\n", "\u3000"])
def test_names_of_only_white_space_are_422(client: TestClient, auth: dict[str, str], name: str) -> None:
    body = problem(client.post("/v1/demonstrators", json={"name": name}, headers=auth), 422)
    assert body["errors"][0]["pointer"] == "/name"
    demonstrator = make_demonstrator(client, auth)
    response = client.post(
        f"/v1/demonstrators/{demonstrator['id']}/tasks", json={"name": name, "mdp_id": "x"}, headers=auth
    )
    assert any(e["pointer"] == "/name" for e in problem(response, 422)["errors"])


@pytest.mark.parametrize("bad", [True, 1.0, "1"])
def test_only_json_integers_are_states_and_actions(
    client: TestClient, auth: dict[str, str], bad: Any
) -> None:
    task = make_task(client, auth)
    trajectories = [{"states": [0, bad], "actions": [1]}]
    response = client.post(
        f"/v1/tasks/{task['id']}/demonstrations", json={"trajectories": trajectories}, headers=auth
    )
    assert problem(response, 422)["errors"][0]["pointer"] == "/trajectories/0/states/1"
    assert client.get(f"/v1/tasks/{task['id']}", headers=auth).json()["n_trajectories"] == 0


def test_a_json_route_answers_415_to_another_media_type(client: TestClient, auth: dict[str, str]) -> None:
    for kind in ("text/plain", "application/x-www-form-urlencoded", "application/xml"):
        response = client.post(
            "/v1/demonstrators", content=b'{"name": "x"}', headers=auth | {"Content-Type": kind}
        )
        assert kind in problem(response, 415)["detail"]
    task = make_task(client, auth)
    response = client.post("/v1/jobs", content=b"{}", headers=auth | {"Content-Type": "text/plain"})
    problem(response, 415)
    response = client.put(
        f"/v1/tasks/{task['id']}/true-reward", content=b"[]", headers=auth | {"Content-Type": "text/csv"}
    )
    problem(response, 415)
    ok = client.post(
        "/v1/demonstrators",
        content=b'{"name": "x"}',
        headers=auth | {"Content-Type": "application/json; charset=utf-8"},
    )
    assert ok.status_code == 201


def test_malformed_json_points_at_the_body_and_names_line_and_column(
    client: TestClient, auth: dict[str, str]
) -> None:
    body = problem(
        client.post("/v1/demonstrators", content=b'{\n  "name": "x",\n}', headers=auth | JSON), 422
    )
    assert body["errors"][0]["pointer"] == ""
    assert "line 3 column 1" in body["errors"][0]["message"] and "not valid JSON" in body["detail"]


def test_a_malformed_multipart_body_is_422(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    malformed = b"--b\r\n-10880--b--\r\n"  # found by schemathesis: was Starlette's undocumented 400
    for route in ("/v1/mdps", f"/v1/tasks/{task['id']}/demonstrations"):
        response = client.post(
            route, content=malformed, headers=auth | {"Content-Type": "multipart/form-data; boundary=b"}
        )
        assert problem(response, 422)["errors"][0]["pointer"] == ""


def test_every_v1_route_documents_401_and_the_503_of_a_database_outage(app: FastAPI) -> None:
    for path, item in app.openapi()["paths"].items():
        if path.startswith("/v1/"):
            for method, operation in item.items():
                assert {"401", "503"} <= set(operation["responses"]), (method, path)
                assert "Retry-After" in operation["responses"]["503"]["headers"], (method, path)


def test_json_that_is_not_utf8_is_422(client: TestClient, auth: dict[str, str]) -> None:
    for route in ("/v1/demonstrators", "/v1/mdps"):
        body = problem(
            client.post(route, content='{"name": "Müller"}'.encode("latin-1"), headers=auth | JSON), 422
        )
        assert body["errors"][0]["pointer"] == "" and "UTF-8" in body["detail"]


def test_an_empty_cursor_is_the_first_page(client: TestClient, auth: dict[str, str]) -> None:
    make_demonstrator(client, auth)
    first = client.get("/v1/demonstrators", headers=auth).json()
    for path in ("/v1/demonstrators?cursor=", "/v1/jobs?cursor=", "/v1/mdps?cursor=&limit=20"):
        response = client.get(path, headers=auth)
        assert response.status_code == 200, (path, response.text)
    assert client.get("/v1/demonstrators?cursor=", headers=auth).json() == first


def test_405_allow_lists_every_method_of_the_path(
    app: FastAPI, client: TestClient, auth: dict[str, str]
) -> None:
    paths = app.openapi()["paths"]
    for template, concrete in (
        ("/v1/demonstrators", "/v1/demonstrators"),
        ("/v1/demonstrators/{demonstrator_id}", "/v1/demonstrators/dem_x"),
        ("/v1/jobs/{job_id}", "/v1/jobs/job_x"),
        ("/v1/tasks/{task_id}/true-reward", "/v1/tasks/task_x/true-reward"),
    ):
        response = client.patch(concrete, headers=auth)
        problem(response, 405)
        allowed = {m.strip() for m in response.headers["allow"].split(",")}
        assert allowed == {m.upper() for m in paths[template]}, (template, allowed)
    # A URL whose resource is made by POST, followed with GET, says so (the motion comparison's png link).
    detail = problem(client.get("/v1/motion-comparisons", headers=auth), 405)["detail"]
    assert detail == "GET is not allowed on /v1/motion-comparisons: it takes POST."


def test_an_unknown_route_is_a_404_problem_that_says_where_the_routes_are(client: TestClient) -> None:
    """A base URL that already ends in /v1 doubles it: the answer says the routes are each under /v1."""
    answer = problem(client.get("/v1/v1/jobs"), 404)
    assert answer["detail"] == "Nothing is at /v1/v1/jobs: /docs lists the API's routes, each under /v1."


def test_a_repeated_query_parameter_s_bad_item_names_the_parameter(
    client: TestClient, auth: dict[str, str]
) -> None:
    error = problem(client.get("/v1/jobs", params={"status": "bogus"}, headers=auth), 422)["errors"][0]
    assert error["parameter"] == "status" and error["message"].startswith("query parameter status: ")


def test_job_routes_document_their_problem_responses(app: FastAPI) -> None:
    for path, item in app.openapi()["paths"].items():
        if path.startswith("/v1/jobs"):
            for method, operation in item.items():
                assert {"401", "404"} <= set(operation["responses"]), (method, path)
    assert "415" in app.openapi()["paths"]["/v1/jobs"]["post"]["responses"]
