"""The metairl lab client: numpy in, numpy out, over the HTTP API (docs/api.md).

Every request goes through `Client._request`, the one place that turns an error answer (RFC 9457
``application/problem+json``, or any other non-2xx response) into a `MetairlError`.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Protocol

import httpx
import numpy as np

TERMINAL_STATUSES = frozenset({"succeeded", "failed", "cancelled"})
"""Job statuses after which a job never changes again."""


class MetairlError(Exception):
    """Any error answer of the service, carrying its problem+json: ``status``, ``title``, ``detail``,
    ``errors`` (``[{"pointer" or "parameter", "message"}]``) and the whole body as ``problem``."""

    def __init__(
        self,
        *,
        status: int,
        title: str,
        detail: str,
        errors: Sequence[Mapping[str, Any]] = (),
        request: str = "",
        problem: Mapping[str, Any] | None = None,
    ):
        self.status, self.title, self.detail = status, title, detail
        self.errors = [dict(e) for e in errors]
        self.request = request
        self.problem: dict[str, Any] = dict(problem or {"status": status, "title": title, "detail": detail})
        super().__init__(self.describe())

    @classmethod
    def from_response(cls, response: httpx.Response) -> MetairlError:
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
        return cls(
            status=int(body.get("status", response.status_code)),
            title=str(body.get("title", response.reason_phrase)),
            detail=str(body.get("detail", "")),
            errors=[e for e in body.get("errors") or [] if isinstance(e, dict)],
            request=request,
            problem=body,
        )

    def describe(self) -> str:
        """``HTTP 422 Invalid input (POST /v1/mdps): detail`` and one indented line per field error."""
        where = f" ({self.request})" if self.request else ""
        head = f"HTTP {self.status} {self.title}{where}"
        lines = [f"{head}: {self.detail}" if self.detail else head]
        lines += [
            f"  - {e.get('pointer') or e.get('parameter') or '/'}: {e.get('message', '')}"
            for e in self.errors
        ]
        return "\n".join(lines)


class TrajectoryLike(Protocol):
    """A trajectory: integer arrays of visited states and the actions taken (one fewer, or as many)."""

    @property
    def states(self) -> np.ndarray: ...

    @property
    def actions(self) -> np.ndarray: ...


@dataclass(frozen=True)
class JobState:
    """A job's status, its progress step (None before the first) and its error when it failed."""

    id: str
    status: str
    step: int | None
    max_steps: int | None
    error: str | None
    started_at: datetime | None = None
    finished_at: datetime | None = None
    attempt: int = 0
    """The attempt the status and step belong to (0 before the first)."""
    updated_at: datetime | None = None
    """When the status last changed."""

    @property
    def finished(self) -> bool:
        """True once the job succeeded, failed or was cancelled."""
        return self.status in TERMINAL_STATUSES

    def already_shows(self, kind: str | None, event: dict[str, Any]) -> bool:
        """Whether this snapshot already reflects a job event (``kind`` and its JSON data): an earlier
        attempt's, a status change before `updated_at`, or a progress step of this attempt at or before
        `step`. A stream opened on a running job replays such history first."""
        attempt = int(event.get("attempt", 0))
        if attempt != self.attempt:
            return attempt < self.attempt
        if kind == "status":
            at = _when(event.get("at"))
            return at is not None and self.updated_at is not None and at <= self.updated_at
        step = event.get("step")
        return kind == "progress" and step is not None and self.step is not None and step <= self.step


@dataclass(frozen=True)
class JobRewardIds:
    """`GET /v1/jobs/{id}/rewards`: the baseline's reward id and each task's, keyed by task id."""

    baseline: str
    tasks: dict[str, str]
    task_names: dict[str, str] = field(default_factory=dict)
    """Each task's name, keyed by task id."""


class Client:
    """A lab's connection to a metairl service: ``Client(url, api_key)``, or ``Client(http)`` around an
    `httpx.Client` that already carries base URL and key. Use it as a context manager to close it."""

    def __init__(self, url: str | httpx.Client, api_key: str | None = None, *, timeout_s: float = 60.0):
        if isinstance(url, str):
            headers = {"Authorization": f"Bearer {api_key}"} if api_key else {}
            self.http = httpx.Client(base_url=url.rstrip("/"), headers=headers, timeout=timeout_s)
        else:
            self.http = url

    @classmethod
    def connect(cls, *, url: str, api_key: str, timeout_s: float = 60.0) -> Client:
        """A client of the service at ``url`` authenticating with ``api_key`` (Bearer)."""
        return cls(url, api_key, timeout_s=timeout_s)

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the underlying HTTP connections."""
        self.http.close()

    def _request(
        self,
        method: str,
        path: str,
        *,
        json: Any = None,
        params: Mapping[str, str] | None = None,
        files: Mapping[str, tuple[str, bytes, str]] | None = None,
        data: Mapping[str, str] | None = None,
    ) -> httpx.Response:
        """Send one request; raises `MetairlError` for any non-2xx answer."""
        response = self.http.request(method, path, json=json, params=params, files=files, data=data)
        if response.is_error:
            raise MetairlError.from_response(response)
        return response

    def _json(self, method: str, path: str, **kwargs: Any) -> Any:
        """Send one request and return its JSON body (None when empty)."""
        response = self._request(method, path, **kwargs)
        return response.json() if response.content else None

    # -------------------------------------------------------------- inputs

    def check_health(self) -> None:
        """`GET /healthz`: fails early, with a clear error, when nothing answers at the URL."""
        self._json("GET", "/healthz")

    def create_mdp(self, body: dict[str, Any]) -> str:
        """`POST /v1/mdps` with an explicit or grid MDP body; returns the MDP id."""
        return str(self._json("POST", "/v1/mdps", json=body)["id"])

    def upload_mdp(
        self,
        *,
        name: str,
        gamma: float,
        arrays: Mapping[str, np.ndarray],
        layout: tuple[int, int, int] | None = None,
        n_states: int | None = None,
        n_actions: int | None = None,
    ) -> str:
        """`POST /v1/mdps` with the arrays as an ``.npz`` upload (``features``, and ``next_state`` or
        ``s``, ``a``, ``next``, ``p``); ``layout`` is (width, height, channels). Returns the MDP id."""
        form = {"name": name, "gamma": repr(float(gamma))}
        if layout is not None:
            form |= {"width": str(layout[0]), "height": str(layout[1]), "channels": str(layout[2])}
        if n_states is not None:
            form["n_states"] = str(n_states)
        if n_actions is not None:
            form["n_actions"] = str(n_actions)
        files = {"file": ("mdp.npz", _npz(arrays), "application/octet-stream")}
        return str(self._json("POST", "/v1/mdps", files=files, data=form)["id"])

    def get_mdp(self, mdp_id: str) -> dict[str, Any]:
        """`GET /v1/mdps/{id}`: the MDP resource (``n_states``, ``n_actions``, ``gamma``, checksums, …)."""
        return dict(self._json("GET", f"/v1/mdps/{mdp_id}"))

    def mdp_arrays(self, mdp_id: str) -> dict[str, np.ndarray]:
        """`GET /v1/mdps/{id}/arrays`: the MDP's arrays under the names `upload_mdp` takes."""
        content = self._request("GET", f"/v1/mdps/{mdp_id}/arrays").content
        with np.load(io.BytesIO(content), allow_pickle=False) as archive:
            return {name: archive[name] for name in archive.files}

    def create_demonstrator(self, *, name: str, metadata: dict[str, Any] | None = None) -> str:
        """`POST /v1/demonstrators`; returns the demonstrator id."""
        return str(self._json("POST", "/v1/demonstrators", json={"name": name, "metadata": metadata})["id"])

    def create_task(
        self, demonstrator_id: str, *, name: str, mdp_id: str, metadata: dict[str, Any] | None = None
    ) -> str:
        """`POST /v1/demonstrators/{id}/tasks`; returns the task id."""
        body = {"name": name, "mdp_id": mdp_id, "metadata": metadata}
        return str(self._json("POST", f"/v1/demonstrators/{demonstrator_id}/tasks", json=body)["id"])

    def add_demonstrations(
        self, task_id: str, trajectories: Iterable[TrajectoryLike | tuple[Sequence[int], Sequence[int]]]
    ) -> str:
        """`POST /v1/tasks/{id}/demonstrations` with every trajectory, given as objects with ``states`` and
        ``actions`` or as (states, actions) pairs of integer arrays. Returns the upload batch's id."""
        body = {
            "trajectories": [
                {"states": np.asarray(s).tolist(), "actions": np.asarray(a).tolist()}
                for s, a in (_states_actions(t) for t in trajectories)
            ]
        }
        return str(self._json("POST", f"/v1/tasks/{task_id}/demonstrations", json=body)["id"])

    def upload_recording(
        self,
        demonstrator_id: str,
        file: Path | bytes,
        *,
        mdp_id: str,
        bounds: Mapping[str, float],
        name: str | None = None,
        plate: Mapping[str, Any] | None = None,
    ) -> dict[str, Any]:
        """`POST /v1/demonstrators/{id}/recordings` with a recording file on a plate of ``bounds`` (``x_min``,
        ``x_max``, ``y_min``, ``y_max``), mapped onto the velocity grid ``mdp_id``: a CSV of centre-of-pressure
        samples (columns ``t,x,y`` and optionally ``instruction``), a C3D file, or a CSV of plate forces and
        moments (``Fx,Fy,Fz,Mx,My,Mz``); the service tells them apart. ``plate`` says how to read a force-plate
        file (``axes``, ``min_fz``, ``platform``, ``rate_hz``, ``moment_unit``, ``origin_depth``; docs/motion.md,
        "Force-plate files"). Returns the recording (its ``tasks``, each with ``task_id`` and ``label``,
        ``n_samples``, ``segments``)."""
        content = file.read_bytes() if isinstance(file, Path) else file
        filename = file.name if isinstance(file, Path) else "recording"
        form = {"mdp_id": mdp_id, "bounds": json.dumps(dict(bounds))}
        form |= ({"name": name} if name else {}) | ({"plate": json.dumps(dict(plate))} if plate else {})
        files = {"file": (filename, content, "application/octet-stream")}
        path = f"/v1/demonstrators/{demonstrator_id}/recordings"
        return dict(self._json("POST", path, files=files, data=form))

    def put_true_reward(self, task_id: str, values: np.ndarray | Sequence[float]) -> None:
        """`PUT /v1/tasks/{id}/true-reward`: the simulation's ground truth, one value per state."""
        self._json("PUT", f"/v1/tasks/{task_id}/true-reward", json={"values": np.asarray(values).tolist()})

    # -------------------------------------------------------------- jobs

    def submit_job(
        self,
        demonstrator_id: str,
        *,
        task_ids: Sequence[str] | None = None,
        config: dict[str, Any] | None = None,
    ) -> JobState:
        """`POST /v1/jobs` (202): fit the demonstrator's tasks (all unless ``task_ids``); the new job's state."""
        body: dict[str, Any] = {"demonstrator_id": demonstrator_id, "config": config}
        if task_ids is not None:
            body["task_ids"] = list(task_ids)
        return _job_state(self._json("POST", "/v1/jobs", json=body))

    def get_job(self, job_id: str) -> JobState:
        """`GET /v1/jobs/{id}`: status and progress."""
        return _job_state(self._json("GET", f"/v1/jobs/{job_id}"))

    def cancel_job(self, job_id: str) -> None:
        """`POST /v1/jobs/{id}/cancel` (409 when it already finished)."""
        self._json("POST", f"/v1/jobs/{job_id}/cancel")

    def wait(
        self,
        job_id: str,
        *,
        poll_s: float = 0.5,
        timeout_s: float | None = None,
        progress: bool = True,
        stream: IO[str] | None = None,
    ) -> JobState:
        """Follow the job until it succeeds, fails or is cancelled, drawing a progress bar on ``stream``
        (stderr by default; none if ``progress`` is false). Returns the final state; `TimeoutError` after
        ``timeout_s``. A failed job is returned, not raised: its ``error`` says what to change.

        The job's events arrive as Server-Sent Events (one connection, resumed with ``Last-Event-ID`` if
        it drops); a server without the stream is polled every ``poll_s`` instead."""
        out = stream if stream is not None else sys.stderr
        deadline = None if timeout_s is None else time.monotonic() + timeout_s

        def draw(state: JobState) -> None:
            if progress:
                out.write("\r" + progress_bar(state))
                out.flush()

        def check_deadline(state: JobState) -> None:
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"job {job_id} is still {state.status} after {timeout_s} s")

        state = self.get_job(job_id)
        draw(state)
        if not state.finished:
            with contextlib.suppress(_NoStream):  # an older server: poll
                state = self._follow(job_id, state, draw=draw, check_deadline=check_deadline)
        while not state.finished:
            check_deadline(state)
            time.sleep(poll_s)
            state = self.get_job(job_id)
            draw(state)
        if progress:
            out.write("\n")
        return state

    def _follow(
        self,
        job_id: str,
        state: JobState,
        *,
        draw: Callable[[JobState], None],
        check_deadline: Callable[[JobState], None],
    ) -> JobState:
        """Read the job's event stream until its final status (reconnecting after the last event seen);
        `_NoStream` when the server does not stream or the connection keeps failing."""
        last_id: str | None = None
        failures = 0
        while True:
            headers = {"Accept": "text/event-stream"} | ({"Last-Event-ID": last_id} if last_id else {})
            try:
                with self.http.stream("GET", f"/v1/jobs/{job_id}/events", headers=headers) as response:
                    if response.is_error:
                        response.read()
                        raise MetairlError.from_response(response)
                    if not response.headers.get("content-type", "").startswith("text/event-stream"):
                        raise _NoStream
                    for event_id, kind, data in _sse_messages(response.iter_lines()):
                        check_deadline(state)
                        last_id = event_id or last_id
                        failures = 0
                        if state.already_shows(kind, data):
                            continue  # history the stream replays: drawing it would move the bar back
                        attempt = int(data.get("attempt", state.attempt))
                        if kind == "progress":
                            state = replace(
                                state, step=data.get("step"), max_steps=data.get("max_steps"), attempt=attempt
                            )
                        elif kind == "status":
                            state = replace(
                                state,
                                status=str(data.get("status")),
                                attempt=attempt,
                                updated_at=_when(data.get("at")),
                            )
                        if kind is not None:
                            draw(state)
                        if state.finished:
                            return self.get_job(job_id)  # the final row: error, last progress
            except httpx.TransportError as exc:
                failures += 1
                if failures > 3:
                    raise _NoStream from exc
                time.sleep(0.5 * failures)
            check_deadline(state)
            state = self.get_job(job_id)  # the stream ended (its time limit, or a drop): resume after last_id
            if state.finished:
                return state

    # -------------------------------------------------------------- results

    def job_rewards(self, job_id: str) -> JobRewardIds:
        """`GET /v1/jobs/{id}/rewards`: reward ids of the baseline and of every task."""
        body = self._json("GET", f"/v1/jobs/{job_id}/rewards")
        return JobRewardIds(
            baseline=str(body["baseline"]["reward_id"]),
            tasks={str(t["task_id"]): str(t["reward_id"]) for t in body["tasks"]},
            task_names={str(t["task_id"]): str(t["task_name"]) for t in body["tasks"] if t.get("task_name")},
        )

    def reward_values(self, reward_id: str, *, quantity: str = "reward") -> np.ndarray:
        """`GET /v1/rewards/{id}?format=npy`: a reward (or a task's ``value`` or ``policy``) as float64."""
        content = self._request(
            "GET", f"/v1/rewards/{reward_id}", params={"format": "npy", "quantity": quantity}
        ).content
        return np.load(io.BytesIO(content), allow_pickle=False).astype(np.float64)

    def reward_png(self, reward_id: str) -> bytes:
        """`GET /v1/rewards/{id}?format=png`: the reward as a heatmap (an MDP with a grid layout)."""
        return self._request("GET", f"/v1/rewards/{reward_id}", params={"format": "png"}).content

    def compare(
        self,
        reward_id: str,
        other: str | Sequence[float] | np.ndarray,
        *,
        states: str = "all",
        other_is_task: bool = False,
    ) -> dict[str, Any]:
        """`POST /v1/comparisons`: learned reward ``reward_id`` against ``other`` — another reward id, a
        task id (``other_is_task``: its true reward) or one value per state — on ``all`` states or the
        ``visited`` ones. Returns the comparison (``pearson``, ``spearman``, ``epic_distance``,
        ``n_compared``, ``dynamics``, …)."""
        if isinstance(other, str):
            b: dict[str, Any] = {"task_id": other} if other_is_task else {"reward_id": other}
        else:
            b = {"values": np.asarray(other, dtype=np.float64).tolist()}
        body = {"a": {"reward_id": reward_id}, "b": b, "states": states}
        return dict(self._json("POST", "/v1/comparisons", json=body))

    def comparison_matrix_png(self, job_id: str) -> bytes:
        """`GET /v1/jobs/{id}/comparison-matrix?format=png`: pairwise Pearson of the job's rewards as a PNG."""
        return self._request("GET", f"/v1/jobs/{job_id}/comparison-matrix", params={"format": "png"}).content

    def rewards(self, job_id: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """A succeeded job's learned rewards: the baseline, and each task's keyed by task id."""
        ids = self.job_rewards(job_id)
        return self.reward_values(ids.baseline), {t: self.reward_values(r) for t, r in ids.tasks.items()}


class _NoStream(Exception):
    """The server did not answer with an event stream (an older server): the client polls instead."""


def _sse_messages(lines: Iterable[str]) -> Iterator[tuple[str | None, str | None, dict[str, Any]]]:
    """(id, event, JSON data) of each Server-Sent Events message; comment and retry lines yield nothing."""
    event_id: str | None = None
    kind: str | None = None
    data: list[str] = []
    for line in lines:
        if line == "":
            if data:
                yield event_id, kind, json.loads("\n".join(data))
            event_id, kind, data = None, None, []
            continue
        if line.startswith(":"):
            continue
        name, _, value = line.partition(":")
        value = value.removeprefix(" ")
        if name == "id":
            event_id = value
        elif name == "event":
            kind = value
        elif name == "data":
            data.append(value)


def progress_bar(state: JobState, *, width: int = 30) -> str:
    """One line: ``job_… running [#######-------]  120/500`` (no bar before the first step)."""
    if state.step is None or not state.max_steps:
        return f"{state.id} {state.status}"
    done = min(1.0, state.step / state.max_steps)
    bar = "#" * round(done * width) + "-" * (width - round(done * width))
    return f"{state.id} {state.status} [{bar}] {state.step:>5}/{state.max_steps}"


def _npz(arrays: Mapping[str, np.ndarray]) -> bytes:
    """The arrays as an ``.npz`` archive (never pickled)."""
    buffer = io.BytesIO()
    named: dict[str, Any] = {name: np.asarray(value) for name, value in arrays.items()}
    np.savez(buffer, **named)
    return buffer.getvalue()


def _states_actions(t: TrajectoryLike | tuple[Sequence[int], Sequence[int]]) -> tuple[Any, Any]:
    """(states, actions) of a trajectory object or pair."""
    if isinstance(t, tuple):
        return t
    return t.states, t.actions


def _job_state(body: dict[str, Any]) -> JobState:
    """The `JobState` of a job resource (progress is null until the worker reports a step)."""
    progress = body.get("progress") or {}
    return JobState(
        id=str(body["id"]),
        status=str(body["status"]),
        step=progress.get("step"),
        max_steps=progress.get("max_steps"),
        error=body.get("error"),
        started_at=_when(body.get("started_at")),
        finished_at=_when(body.get("finished_at")),
        attempt=int(body.get("attempts") or 0),
        updated_at=_when(body.get("updated_at")),
    )


def _when(text: str | None) -> datetime | None:
    """An ISO 8601 timestamp of the API, or None."""
    return datetime.fromisoformat(text) if text else None
