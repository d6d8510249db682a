"""What the client makes of the API's JSON and how its errors travel: job states, reward ids, pickled errors,
and the service URL checked when a client is made."""

from __future__ import annotations

import asyncio
import pickle
from datetime import UTC, datetime

import httpx
import pytest

from metairl_client import (
    APIConnectionError,
    AsyncClient,
    Client,
    InvalidRequestError,
    JobRewardIds,
    JobState,
    MetairlError,
    NotFoundError,
    UnprocessableEntityError,
)
from metairl_client._errors import error_from_response
from metairl_client._waiting import Waiter

JOB = {
    "id": "job_1",
    "created_at": "2026-01-05T10:05:00Z",
    "demonstrator_id": "dem_1",
    "task_ids": ["task_1", "task_2"],
    "status": "running",
    "config": {"method": "meta_irl", "max_steps": 500},
    "progress": {
        "step": 120,
        "max_steps": 500,
        "loss": 0.8,
        "irl_loss": 0.5,
        "sharing_loss": 0.3,
        "heldout_nll": 0.7,
        "elapsed_s": 4.5,
    },
    "error": None,
    "attempts": 1,
    "max_attempts": 3,
    "cancel_requested": False,
    "best_step": None,
    "shrinkage": None,
    "sparsity": None,
    "updated_at": "2026-01-05T10:05:15Z",
    "started_at": "2026-01-05T10:05:01Z",
    "finished_at": None,
    "a_field_the_client_does_not_name": 1,
}


def test_a_job_state_carries_every_field_of_the_job_resource() -> None:
    state = JobState.from_json(JOB)
    assert (state.demonstrator_id, state.task_ids, state.config["max_steps"]) == (
        "dem_1",
        ("task_1", "task_2"),
        500,
    )
    assert state.created_at == datetime(2026, 1, 5, 10, 5, tzinfo=UTC)
    assert (state.step, state.max_steps, state.attempt, state.max_attempts) == (120, 500, 1, 3)
    assert (state.loss, state.irl_loss, state.sharing_loss, state.heldout_nll, state.elapsed_s) == (
        0.8,
        0.5,
        0.3,
        0.7,
        4.5,
    )
    assert state.cancel_requested is False and state.best_step is None
    assert state.body["a_field_the_client_does_not_name"] == 1
    assert hash(state) == hash(JobState.from_json(JOB))  # still usable in sets and as a key


def test_a_job_state_before_the_first_step_has_no_losses() -> None:
    state = JobState.from_json(JOB | {"progress": None, "status": "queued"})
    assert (state.step, state.loss, state.elapsed_s) == (None, None, None)


def test_a_progress_event_moves_the_losses_of_the_waited_state() -> None:
    with Waiter("job_1", timeout_s=None, progress=False, stream=None) as waiter:
        waiter.show(JobState.from_json(JOB))
        event = {"attempt": 1, "step": 130, "max_steps": 500, "loss": 0.6, "irl_loss": 0.4, "elapsed_s": 5.0}
        waiter.on_event("7", "progress", event)
        assert (waiter.current.step, waiter.current.loss, waiter.current.irl_loss) == (130, 0.6, 0.4)
        assert waiter.current.elapsed_s == 5.0 and waiter.current.task_ids == ("task_1", "task_2")


def test_job_reward_ids_carry_the_truth_scores_and_the_number_of_states() -> None:
    def reward(task: str | None, truth: float | None = None) -> dict[str, object]:
        return {
            "reward_id": f"rwd_{task}",
            "task_id": task,
            "task_name": task,
            "n_states": 25,
            "truth_pearson": truth,
        }

    body = {"baseline": reward(None), "tasks": [reward("task_1", 0.9), reward("task_2")]}
    ids = JobRewardIds.from_json(body)
    assert ids.truth_pearson == {"task_1": 0.9} and ids.n_states == 25
    assert ids.tasks == {"task_1": "rwd_task_1", "task_2": "rwd_task_2"}


def test_an_error_survives_pickling_whole() -> None:
    request = httpx.Request("POST", "http://metairl.test/v1/jobs")
    problem = {
        "type": "/problems/validation",
        "title": "Invalid input",
        "status": 422,
        "detail": "The request is invalid.",
        "errors": [{"pointer": "/config/max_steps", "message": "Input should be greater than or equal to 1"}],
    }
    answer = httpx.Response(422, json=problem, request=request, headers={"Retry-After": "3"})
    errors: list[MetairlError] = [
        error_from_response(answer),
        error_from_response(httpx.Response(404, json={"title": "Not found", "status": 404}, request=request)),
        APIConnectionError(httpx.ConnectError("refused"), request="GET /healthz"),
        InvalidRequestError(ValueError("NaN"), request="PUT /v1/tasks/task_1/true-reward"),
    ]
    for error in errors:
        copy = pickle.loads(pickle.dumps(error))
        assert type(copy) is type(error) and str(copy) == str(error)
        assert (copy.status, copy.title, copy.detail, copy.errors, copy.problem, copy.request) == (
            error.status,
            error.title,
            error.detail,
            error.errors,
            error.problem,
            error.request,
        )
    unprocessable = pickle.loads(pickle.dumps(errors[0]))
    assert isinstance(unprocessable, UnprocessableEntityError) and unprocessable.retry_after_s == 3.0
    assert isinstance(pickle.loads(pickle.dumps(errors[1])), NotFoundError)


@pytest.mark.parametrize("url", ["127.0.0.1:8000", "localhost:8000", "ftp://127.0.0.1:8000", "http://[::1"])
def test_a_service_url_without_http_is_refused_when_the_client_is_made(url: str) -> None:
    with pytest.raises(ValueError, match="http://"):
        Client(url, "key")

    async def make() -> None:
        AsyncClient(url, "key")

    with pytest.raises(ValueError, match="http://"):
        asyncio.run(make())


def test_a_service_url_keeps_its_path_without_the_trailing_slash() -> None:
    with Client("https://lab.example.org/metairl/", "key") as lab:
        assert str(lab.http.base_url) == "https://lab.example.org/metairl/"
        assert lab.http.build_request("GET", "/v1/jobs").url.path == "/metairl/v1/jobs"


def test_an_errors_text_lists_a_field_error_once() -> None:
    """The service's detail repeats its first field error: with one, the text does not say it twice; with
    more, each is listed."""
    request = httpx.Request("POST", "http://metairl.test/v1/jobs")
    one = {"pointer": "/config/max_steps", "message": "Input should be greater than or equal to 1"}
    other = {"pointer": "/config/ensemble", "message": "Input should be less than or equal to 16"}

    def text(errors: list[dict[str, str]]) -> str:
        problem = {"title": "Invalid input", "status": 422, "errors": errors}
        detail = f"The request is invalid. {one['pointer']}: {one['message']}"
        return str(
            error_from_response(httpx.Response(422, json=problem | {"detail": detail}, request=request))
        )

    assert text([one]).count(one["message"]) == 1 and "\n" not in text([one])
    assert text([one, other]).count(one["message"]) == 2 and text([one, other]).count("\n  - ") == 2
