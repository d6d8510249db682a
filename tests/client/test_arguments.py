"""What the client does with arguments before sending them: one task id where a list is expected is that
one task, and a NaN a JSON body cannot carry is a `MetairlError` raised before anything is sent."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from metairl_client import Client, InvalidRequestError, MetairlError
from tests.service.helpers import add_demonstrations, make_task


def test_one_task_id_given_as_a_string_submits_that_task(client: TestClient, auth: dict[str, str]) -> None:
    task = make_task(client, auth)
    add_demonstrations(client, auth, task["id"])
    client.headers.update(auth)
    job = Client(client).submit_job(task["demonstrator_id"], task_ids=task["id"])
    assert client.get(f"/v1/jobs/{job.id}").json()["task_ids"] == [task["id"]]


def test_a_nan_in_a_json_body_is_a_metairl_error_and_nothing_is_sent(client: TestClient) -> None:
    sent: list[str] = []
    client.event_hooks["request"].append(lambda request: sent.append(str(request.url)))
    with pytest.raises(InvalidRequestError) as refused:
        Client(client).compare("rwd_x", np.array([np.nan, 1.0]))
    assert isinstance(refused.value, MetairlError) and "nothing was sent" in str(refused.value)
    assert refused.value.request == "POST /v1/comparisons" and sent == []
