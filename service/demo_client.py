"""A small typed HTTP client of the metairl API (API.md) for `metairl demo`.

Every request goes through `ApiClient._request`, the one place that turns an error response
(RFC 9457 ``application/problem+json``, or any other non-2xx answer) into a `ServiceError` whose text
names the status, title, detail and each ``errors[]`` pointer with its message.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import httpx
import numpy as np

from metairl_engine.demos import Trajectory

TERMINAL_STATUSES = frozenset({"succeeded", "failed", "cancelled"})
"""Job statuses (API.md §5 contract) after which a job never changes again."""


class ServiceError(Exception):
    """An error answer of the service, formatted for people: status, title, detail and field errors."""

    def __init__(
        self,
        *,
        status: int,
        title: str,
        detail: str,
        errors: Sequence[tuple[str, str]] = (),
        request: str = "",
    ):
        self.status, self.title, self.detail = status, title, detail
        self.errors = list(errors)
        self.request = request
        super().__init__(self.describe())

    @classmethod
    def from_response(cls, response: httpx.Response) -> ServiceError:
        """Read a problem+json body (or, failing that, the raw text) of a non-2xx response."""
        request = f"{response.request.method} {response.request.url.path}"
        try:
            body = response.json()
        except ValueError:
            body = None
        if not isinstance(body, dict):
            return cls(
                status=response.status_code,
                title=response.reason_phrase or "Error",
                detail=response.text.strip()[:500],
                request=request,
            )
        errors = [
            (str(e.get("pointer") or e.get("parameter") or "/"), str(e.get("message", "")))
            for e in body.get("errors") or []
            if isinstance(e, dict)
        ]
        return cls(
            status=int(body.get("status", response.status_code)),
            title=str(body.get("title", response.reason_phrase)),
            detail=str(body.get("detail", "")),
            errors=errors,
            request=request,
        )

    def describe(self) -> str:
        """``HTTP 422 Invalid input (POST /v1/mdps): detail`` and one indented line per field error."""
        where = f" ({self.request})" if self.request else ""
        head = f"HTTP {self.status} {self.title}{where}"
        lines = [f"{head}: {self.detail}" if self.detail else head]
        lines += [f"  - {pointer}: {message}" for pointer, message in self.errors]
        return "\n".join(lines)


@dataclass(frozen=True)
class JobState:
    """What the demo needs of `GET /v1/jobs/{id}`: status, progress step (None before the first) and error."""

    id: str
    status: str
    step: int | None
    max_steps: int | None
    error: str | None

    @property
    def finished(self) -> bool:
        """True once the job succeeded, failed or was cancelled."""
        return self.status in TERMINAL_STATUSES


@dataclass(frozen=True)
class JobRewardIds:
    """`GET /v1/jobs/{id}/rewards`: the baseline's reward id and each task's, keyed by task id."""

    baseline: str
    tasks: dict[str, str]


class ApiClient:
    """The API calls the demo makes, over one `httpx.Client` that already carries base URL and key."""

    def __init__(self, http: httpx.Client):
        self.http = http

    @classmethod
    def connect(cls, *, url: str, api_key: str, timeout_s: float = 60.0) -> ApiClient:
        """A client of the service at ``url`` authenticating with ``api_key`` (Bearer)."""
        return cls(
            httpx.Client(
                base_url=url.rstrip("/"),
                headers={"Authorization": f"Bearer {api_key}"},
                timeout=timeout_s,
            )
        )

    def __enter__(self) -> ApiClient:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.http.close()

    def _request(
        self, method: str, path: str, *, json: Any = None, params: dict[str, str] | None = None
    ) -> Any:
        """Send one request and return its JSON body; raises `ServiceError` for any non-2xx answer."""
        response = self.http.request(method, path, json=json, params=params)
        if response.is_error:
            raise ServiceError.from_response(response)
        return response.json() if response.content else None

    def check_health(self) -> None:
        """`GET /healthz`: fails early, with a clear error, when nothing answers at the URL."""
        self._request("GET", "/healthz")

    def create_mdp(self, body: dict[str, Any]) -> str:
        """`POST /v1/mdps` with an explicit or grid MDP body; returns the MDP id."""
        return str(self._request("POST", "/v1/mdps", json=body)["id"])

    def create_demonstrator(self, *, name: str, metadata: dict[str, Any]) -> str:
        """`POST /v1/demonstrators`; returns the demonstrator id."""
        return str(
            self._request("POST", "/v1/demonstrators", json={"name": name, "metadata": metadata})["id"]
        )

    def create_task(self, demonstrator_id: str, *, name: str, mdp_id: str, metadata: dict[str, Any]) -> str:
        """`POST /v1/demonstrators/{id}/tasks`; returns the task id."""
        body = {"name": name, "mdp_id": mdp_id, "metadata": metadata}
        return str(self._request("POST", f"/v1/demonstrators/{demonstrator_id}/tasks", json=body)["id"])

    def add_demonstrations(self, task_id: str, trajectories: Sequence[Trajectory]) -> None:
        """`POST /v1/tasks/{id}/demonstrations` with every trajectory (final state included)."""
        body = {
            "trajectories": [
                {"states": t.states.tolist(), "actions": t.actions.tolist()} for t in trajectories
            ]
        }
        self._request("POST", f"/v1/tasks/{task_id}/demonstrations", json=body)

    def put_true_reward(self, task_id: str, values: np.ndarray) -> None:
        """`PUT /v1/tasks/{id}/true-reward`: the simulation's ground truth, one value per state."""
        self._request("PUT", f"/v1/tasks/{task_id}/true-reward", json={"values": values.tolist()})

    def submit_job(
        self, demonstrator_id: str, *, task_ids: Sequence[str], config: dict[str, Any]
    ) -> JobState:
        """`POST /v1/jobs` (202); returns the new job's state."""
        body = {"demonstrator_id": demonstrator_id, "task_ids": list(task_ids), "config": config}
        return _job_state(self._request("POST", "/v1/jobs", json=body))

    def get_job(self, job_id: str) -> JobState:
        """`GET /v1/jobs/{id}`: status and progress."""
        return _job_state(self._request("GET", f"/v1/jobs/{job_id}"))

    def cancel_job(self, job_id: str) -> None:
        """`POST /v1/jobs/{id}/cancel` (409 when it already finished)."""
        self._request("POST", f"/v1/jobs/{job_id}/cancel")

    def job_rewards(self, job_id: str) -> JobRewardIds:
        """`GET /v1/jobs/{id}/rewards`: reward ids of the baseline and of every task."""
        body = self._request("GET", f"/v1/jobs/{job_id}/rewards")
        return JobRewardIds(
            baseline=str(body["baseline"]["reward_id"]),
            tasks={str(t["task_id"]): str(t["reward_id"]) for t in body["tasks"]},
        )

    def reward_values(self, reward_id: str) -> np.ndarray:
        """`GET /v1/rewards/{id}?format=json`: the reward as a float64 vector of length n_states."""
        body = self._request("GET", f"/v1/rewards/{reward_id}", params={"format": "json"})
        values = np.asarray(body["values"], dtype=np.float64)
        if values.shape != (int(body["n_states"]),):
            raise ServiceError(
                status=200,
                title="Unexpected reward shape",
                detail=f"reward {reward_id} has shape {values.shape}, expected ({body['n_states']},)",
            )
        return values


def _job_state(body: dict[str, Any]) -> JobState:
    """The `JobState` of a job resource (progress is null until the worker reports a step)."""
    progress = body.get("progress") or {}
    return JobState(
        id=str(body["id"]),
        status=str(body["status"]),
        step=progress.get("step"),
        max_steps=progress.get("max_steps"),
        error=body.get("error"),
    )
