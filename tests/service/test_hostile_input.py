"""Hostile or careless input found by probing the API: every case is a 4xx problem naming what is wrong,
never a 500 (deep JSON, huge or unclosed CSV cells, overflowing numbers, broken URLs, `.npz` headers that
declare huge arrays, NUL characters, seeds past 64 bits)."""

from __future__ import annotations

import io
import json
import zipfile
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.service.helpers import PLATE, created, make_demonstrator, make_task

DEPTH = 60_000
"""Nesting levels of the deep JSON documents (the probe found a RecursionError at 50,000–100,000)."""


def deep(depth: int = DEPTH) -> str:
    """A JSON array nested `depth` levels deep."""
    return "[" * depth + "]" * depth


def problem(response: Any, status: int = 422) -> dict[str, Any]:
    """The problem+json body of a response that must have `status`."""
    assert response.status_code == status, response.text[:500]
    assert response.headers["content-type"].startswith("application/problem+json")
    body: dict[str, Any] = response.json()
    return body


@pytest.mark.parametrize("idempotent", [False, True])
def test_deeply_nested_json_bodies_are_422(
    client: TestClient, auth: dict[str, str], idempotent: bool
) -> None:
    headers = auth | {"Content-Type": "application/json"}
    if idempotent:
        headers |= {"Idempotency-Key": f"deep-{idempotent}"}
    task = make_task(client, auth)
    body = '{"kind": "explicit", "name": "m", "gamma": 0.9, "transitions": ' + deep() + "}"
    for url in ("/v1/mdps", f"/v1/tasks/{task['id']}/demonstrations", "/v1/demonstrators"):
        problem(client.post(url, content=body, headers=headers))


@pytest.mark.parametrize("field", ["bounds", "plate", "grid"])
def test_deeply_nested_json_form_fields_of_a_recording_are_422(
    client: TestClient, auth: dict[str, str], field: str
) -> None:
    demonstrator = make_demonstrator(client, auth)
    form = {"bounds": json.dumps(PLATE), field: deep()}
    response = client.post(
        f"/v1/demonstrators/{demonstrator['id']}/recordings",
        files={"file": ("cop.csv", b"t,x,y\n0,0,0\n")},
        data=form,
        headers=auth,
    )
    assert problem(response)["errors"][0]["pointer"] == f"/{field}"


UNCLOSED = b'"' + b"x" * (200 * 1024)
"""An unclosed quote running on past 128 KiB (Python's csv field limit)."""


def test_a_huge_or_unclosed_csv_cell_in_demonstrations_is_422_naming_the_line(
    client: TestClient, auth: dict[str, str]
) -> None:
    task = make_task(client, auth)
    url = f"/v1/tasks/{task['id']}/demonstrations"
    for payload in (
        b"trajectory,step,state,action\na,0,0,1\n" + UNCLOSED,
        b"trajectory,step,state,action\na,0," + b"1" * (200 * 1024) + b",1\n",
    ):
        body = problem(client.post(url, files={"file": ("d.csv", payload)}, headers=auth))
        assert "line 3" in body["errors"][0]["message"] or "line 2" in body["errors"][0]["message"]


def test_a_huge_or_unclosed_csv_cell_in_a_recording_is_422(client: TestClient, auth: dict[str, str]) -> None:
    demonstrator = make_demonstrator(client, auth)
    url = f"/v1/demonstrators/{demonstrator['id']}/recordings"
    for payload in (b"t,x,y\n0,0,0\n" + UNCLOSED, b"t,x,y,instruction\n" + UNCLOSED):
        response = client.post(
            url, files={"file": ("cop.csv", payload)}, data={"bounds": json.dumps(PLATE)}, headers=auth
        )
        assert "CSV line" in problem(response)["errors"][0]["message"]


def test_an_overflowing_smoothing_window_is_422(client: TestClient, auth: dict[str, str]) -> None:
    demonstrator = make_demonstrator(client, auth)
    samples = [{"t": k / 50, "x": 0.001 * k, "y": 0.0} for k in range(50)]
    body = {
        "bounds": PLATE,
        "grid": {"width": 10, "height": 10},
        "discretise": {"smooth_s": 1e308},
        "samples": samples,
    }
    response = client.post(f"/v1/demonstrators/{demonstrator['id']}/recordings", json=body, headers=auth)
    assert problem(response)["errors"][0]["pointer"] == "/discretise/smooth_s"


@pytest.mark.parametrize(
    "url", ["http://127.0.0.1:99999/", "http://[::1/", "https://[fe80::1%zz/x", "http://:0/"]
)
def test_a_webhook_url_with_a_bad_port_or_ipv6_literal_is_422(
    client: TestClient, auth: dict[str, str], url: str
) -> None:
    assert (
        problem(client.post("/v1/webhooks", json={"url": url}, headers=auth))["errors"][0]["pointer"]
        == "/url"
    )
    assert client.get("/healthz").status_code == 200


def npy_member_declaring(shape: tuple[int, ...], descr: str) -> bytes:
    """A `.npz` whose single member `features` has a header declaring `shape` of dtype `descr` (no data)."""
    header = repr({"descr": descr, "fortran_order": False, "shape": shape}).encode()
    header += b" " * (63 - (len(header) + 10) % 64) + b"\n"
    npy = b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header
    buffer = io.BytesIO()
    np.savez(buffer, next_state=np.zeros((2, 1), dtype=np.int32))
    with zipfile.ZipFile(buffer, "a") as archive:
        archive.writestr("features.npy", npy)
    return buffer.getvalue()


@pytest.mark.parametrize(
    ("shape", "descr"), [((64 * 2**20,), "|V1048576"), ((1000,), "|V1048576"), ((2, 1), "|V16")]
)
def test_an_npz_member_declaring_a_huge_or_void_dtype_is_422_before_reading(
    client: TestClient, auth: dict[str, str], shape: tuple[int, ...], descr: str
) -> None:
    response = client.post(
        "/v1/mdps",
        files={"file": ("mdp.npz", npy_member_declaring(shape, descr))},
        data={"name": "m", "gamma": "0.9"},
        headers=auth,
    )
    assert problem(response)["errors"][0]["pointer"] == "/file"


def test_a_seed_past_64_bits_is_422(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    body = {"demonstrator_id": task["demonstrator_id"], "config": {"seed": 2**70}}
    assert problem(client.post("/v1/jobs", json=body, headers=auth))["errors"][0]["pointer"] == "/config/seed"


NUL_REQUESTS: list[tuple[str, str, dict[str, Any], str]] = [
    ("GET", "/v1/mdps/%00", {}, "mdp_id"),
    ("GET", "/v1/demonstrators/d%00", {}, "demonstrator_id"),
    ("DELETE", "/v1/tasks/%00", {}, "task_id"),
    ("GET", "/v1/jobs/%00/events", {}, "job_id"),
    ("GET", "/v1/mdps?cursor=%00", {}, "cursor"),
    ("GET", "/v1/jobs?status=%00", {}, "status"),
    ("POST", "/v1/demonstrators", {"json": {"name": "a\u0000b"}}, "/name"),
    ("POST", "/v1/demonstrators", {"json": {"name": "a", "metadata": {"k\u0000": 1}}}, "/metadata"),
    ("POST", "/v1/demonstrators", {"json": {"name": "a", "metadata": {"k": ["\u0000"]}}}, "/metadata/k/0"),
    ("POST", "/v1/webhooks", {"json": {"url": "https://example.org/\u0000"}}, "/url"),
    ("POST", "/v1/jobs", {"json": {"demonstrator_id": "\u0000"}}, "/demonstrator_id"),
    (
        "POST",
        "/v1/mdps",
        {"data": {"name": "m\u0000", "gamma": "0.9"}, "files": {"file": ("m.npz", b"x")}},
        "name",
    ),
]


@pytest.mark.parametrize(("method", "url", "kwargs", "field"), NUL_REQUESTS)
def test_a_nul_character_anywhere_is_422_naming_the_field(
    client: TestClient, auth: dict[str, str], method: str, url: str, kwargs: dict[str, Any], field: str
) -> None:
    body = problem(client.request(method, url, headers=auth, **kwargs))
    error = body["errors"][0]
    assert field in (error.get("pointer"), error.get("parameter")), body


def test_a_nul_character_in_a_task_name_or_csv_cell_is_422(client: TestClient, auth: dict[str, str]) -> None:
    demonstrator = make_demonstrator(client, auth)
    response = client.post(
        f"/v1/demonstrators/{demonstrator['id']}/tasks", json={"name": "\u0000", "mdp_id": "x"}, headers=auth
    )
    assert problem(response)["errors"][0]["pointer"] == "/name"
    task = make_task(client, auth)
    csv = b"trajectory,step,state,action\na\x00,0,0,1\na\x00,1,1,\n"
    response = client.post(
        f"/v1/tasks/{task['id']}/demonstrations", files={"file": ("d.csv", csv)}, headers=auth
    )
    assert "line 2" in problem(response)["errors"][0]["message"]
    cop = b"t,x,y,instruction\n0,0,0,fo\x00rward\n"
    response = client.post(
        f"/v1/demonstrators/{demonstrator['id']}/recordings",
        files={"file": ("cop.csv", cop)},
        data={"bounds": json.dumps(PLATE), "grid": json.dumps({"width": 4, "height": 4})},
        headers=auth,
    )
    assert "line 2" in problem(response)["errors"][0]["message"]
    created(client.get("/healthz"), 200)


BAD_ROWS = 100_000
"""Items of a request's array that are all bad: before, one issue each (a 5.4 MB MDP of 200,000 such rows took
an API process to 1.6 GB and answered 60 MB)."""


def array_of_bad_items(
    client: TestClient, auth: dict[str, str], kind: str
) -> tuple[str, dict[str, Any], str]:
    """(path, body, pointer of its first bad item): a request whose one large array holds nothing valid."""
    rows = ["x"] * BAD_ROWS
    transitions: dict[str, Any]
    if kind == "features":
        transitions = {"kind": "deterministic", "next_state": [[0]] * BAD_ROWS}
        body = {
            "kind": "explicit",
            "name": "m",
            "gamma": 0.9,
            "features": [rows[:3]] * BAD_ROWS,
            "transitions": transitions,
        }
        return "/v1/mdps", body, "/features/0/0"
    if kind == "sparse":
        transitions = {
            "kind": "sparse",
            "s": [0] * BAD_ROWS,
            "a": [0] * BAD_ROWS,
            "next": [0] * BAD_ROWS,
            "p": rows,
        }
        return (
            "/v1/mdps",
            {"kind": "explicit", "name": "m", "gamma": 0.9, "transitions": transitions},
            "/transitions/p/0",
        )
    if kind == "webhook events":
        return "/v1/webhooks", {"url": "https://93.184.215.14/hook", "events": rows}, "/events/0"
    task = make_task(client, auth)["id"]
    if kind == "job tasks":
        demonstrator = client.get(f"/v1/tasks/{task}", headers=auth).json()["demonstrator_id"]
        return "/v1/jobs", {"demonstrator_id": demonstrator, "task_ids": [0] * BAD_ROWS}, "/task_ids/0"
    if kind == "trajectories":
        return (
            f"/v1/tasks/{task}/demonstrations",
            {"trajectories": [{"states": rows[:2], "actions": [0]}] * BAD_ROWS},
            "/trajectories/0/states/0",
        )
    if kind == "true reward":
        return f"/v1/tasks/{task}/true-reward", {"values": rows}, "/values/0"
    demonstrator = make_demonstrator(client, auth)["id"]
    samples = [{"t": "x", "x": 0.0, "y": 0.0}] * BAD_ROWS
    return (
        f"/v1/demonstrators/{demonstrator}/recordings",
        {"bounds": PLATE, "grid": {"width": 5, "height": 5}, "samples": samples},
        "/samples/0/t",
    )


@pytest.mark.parametrize(
    "kind", ["features", "sparse", "trajectories", "true reward", "samples", "job tasks", "webhook events"]
)
def test_an_array_of_bad_items_is_one_issue_at_its_first_not_one_per_item(
    client: TestClient, auth: dict[str, str], kind: str
) -> None:
    path, body, pointer = array_of_bad_items(client, auth, kind)
    method = client.put if kind == "true reward" else client.post
    response = method(path, content=json.dumps(body), headers=auth | {"Content-Type": "application/json"})
    assert [e["pointer"] for e in problem(response)["errors"]] == [pointer]
    assert len(response.content) < 10_000
