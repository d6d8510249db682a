"""`upload_recording(..., units=...)` of both clients against the real app: the length unit reaches the
recording and its sway measures, and a unit the file contradicts comes back as the service's 422."""

from __future__ import annotations

import asyncio
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient

from metairl_client import AsyncClient, Client, UnprocessableEntityError
from tests.client.test_against_the_app import Synchronous, ToTestClient, standing_csv


def check_units(lab: Any) -> None:
    """Upload a standing trial in cm and one whose header contradicts the unit sent."""
    stander = lab.create_demonstrator(name="stander")
    trial = lab.upload_recording(stander, standing_csv(0), protocol="standing", units="cm")
    assert trial["settings"]["units"] == "cm"
    assert trial["units"] == "cm"  # beside the settings, as the listing shows it
    assert lab.recording_sway(trial["id"])["units"] == "cm"
    in_mm = b"t,COPx[mm],COPy[mm]\n" + standing_csv(1).split(b"\n", 1)[1]
    with pytest.raises(UnprocessableEntityError) as refused:
        lab.upload_recording(stander, in_mm, protocol="standing", units="cm")
    assert refused.value.errors[0]["pointer"] == "/units"


def test_the_client_sends_the_length_unit_of_a_recording(client: TestClient, auth: dict[str, str]) -> None:
    client.headers.update(auth)
    check_units(Client(client))


def test_the_async_client_sends_the_length_unit_of_a_recording(
    client: TestClient, auth: dict[str, str]
) -> None:
    http = httpx.AsyncClient(transport=ToTestClient(client), base_url=str(client.base_url), headers=auth)
    with asyncio.Runner() as runner:
        check_units(Synchronous(AsyncClient(http), runner))
        runner.run(http.aclose())
