"""Every API operation as a `Call`: path, parameters and body built from typed arguments, and how its answer
is read. `Client` and `AsyncClient` send the same calls, one synchronously and one with ``await``."""

from __future__ import annotations

import io
import json
from collections.abc import Iterable, Mapping, Sequence
from os import PathLike
from pathlib import Path
from typing import Any, Literal
from urllib.parse import quote

import httpx
import numpy as np

from metairl_client._errors import InvalidRequestError
from metairl_client._models import JobRewardIds, JobState, Page, Trajectory
from metairl_client._transport import Call

RewardFormat = Literal["json", "npy", "csv", "png"]
Quantity = Literal["reward", "value", "policy", "uncertainty", "evidence"]
JobStatusName = Literal["queued", "running", "succeeded", "failed", "cancelled"]
WebhookEvent = Literal["job.succeeded", "job.failed", "job.cancelled"]
Protocol = Literal["movements", "standing"]


# -------------------------------------------------------------- reading answers


def _object(response: httpx.Response) -> dict[str, Any]:
    """The JSON object of an answer."""
    return dict(response.json())


def _id(response: httpx.Response) -> str:
    """The ``id`` of a created resource."""
    return str(response.json()["id"])


def _nothing(response: httpx.Response) -> None:
    """An answer whose body does not matter (204, or an acknowledgement)."""


def _content(response: httpx.Response) -> bytes:
    """The raw body (a PNG, CSV or ``.npy`` download)."""
    return response.content


def _npy(response: httpx.Response) -> np.ndarray:
    """An ``.npy`` download as float64."""
    return np.load(io.BytesIO(response.content), allow_pickle=False).astype(np.float64)


def _npz(response: httpx.Response) -> dict[str, np.ndarray]:
    """An ``.npz`` download as named arrays."""
    with np.load(io.BytesIO(response.content), allow_pickle=False) as archive:
        return {name: archive[name] for name in archive.files}


def _job(response: httpx.Response) -> JobState:
    """A job resource as a `JobState`."""
    return JobState.from_json(response.json())


def _page(response: httpx.Response) -> Page:
    """One page of a list."""
    return Page.from_json(response.json())


def _rewards(response: httpx.Response) -> JobRewardIds:
    """The reward ids of a job."""
    return JobRewardIds.from_json(response.json())


def _segment(value: str) -> str:
    """An id as one path segment (escaped, so an id can never reach another route)."""
    return quote(value, safe="")


def _paging(limit: int | None, cursor: str | None, **filters: str | None) -> dict[str, Any]:
    """Query parameters of a list: the filters, ``limit`` and ``cursor``, those given."""
    given = {"limit": limit, "cursor": cursor, **filters}
    return {name: value for name, value in given.items() if value is not None}


def npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    """The arrays as an ``.npz`` archive (never pickled)."""
    buffer = io.BytesIO()
    named: dict[str, Any] = {name: np.asarray(value) for name, value in arrays.items()}
    np.savez(buffer, **named)
    return buffer.getvalue()


def _states_actions(t: Trajectory | Mapping[str, Any], index: int) -> tuple[Any, Any]:
    """(states, actions) of trajectory ``index``, a (states, actions) pair, an object with ``states`` and
    ``actions`` or the JSON body's ``{"states": …, "actions": …}``, as lists; `InvalidRequestError` for
    anything else."""
    states: Any
    actions: Any
    if isinstance(t, tuple) and len(t) == 2:
        states, actions = t
    elif isinstance(t, Mapping) and {"states", "actions"} <= t.keys():
        states, actions = t["states"], t["actions"]
    elif hasattr(t, "states") and hasattr(t, "actions"):
        states, actions = t.states, t.actions
    else:
        problem = TypeError(
            f"trajectory {index} is a {type(t).__name__}: give (states, actions), an object with .states and "
            '.actions, or {"states": [...], "actions": [...]}'
        )
        raise InvalidRequestError(problem, request="POST /v1/tasks/{id}/demonstrations")
    return _whole(states), _whole(actions)


def _whole(values: Any) -> Any:
    """``values`` as JSON lists, floats that are whole numbers (an array from ``np.loadtxt``) as integers, as
    the engine's ``Trajectory.of`` reads them; anything else as given, for the service to name."""
    array = np.asarray(values)
    if array.dtype.kind == "f" and np.isfinite(array).all() and (array == np.round(array)).all():
        array = array.astype(np.int64)
    return array.tolist()


# -------------------------------------------------------------- service


def health() -> Call[None]:
    """`GET /healthz`."""
    return Call("GET", "/healthz", _nothing)


def readiness() -> Call[dict[str, Any]]:
    """`GET /readyz`."""
    return Call("GET", "/readyz", _object)


# -------------------------------------------------------------- MDPs


def create_mdp(body: Mapping[str, Any]) -> Call[str]:
    """`POST /v1/mdps` with a JSON body."""
    return Call("POST", "/v1/mdps", _id, json=dict(body))


def upload_mdp(
    *,
    name: str,
    gamma: float,
    arrays: Mapping[str, np.ndarray],
    layout: tuple[int, int, int] | None,
    n_states: int | None,
    n_actions: int | None,
) -> Call[str]:
    """`POST /v1/mdps` with the arrays as an ``.npz`` upload."""
    form = {"name": name, "gamma": repr(float(gamma))}
    if layout is not None:
        form |= {"width": str(layout[0]), "height": str(layout[1]), "channels": str(layout[2])}
    if n_states is not None:
        form["n_states"] = str(n_states)
    if n_actions is not None:
        form["n_actions"] = str(n_actions)
    files = {"file": ("mdp.npz", npz_bytes(arrays), "application/octet-stream")}
    return Call("POST", "/v1/mdps", _id, files=files, data=form)


def list_mdps(limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/mdps`."""
    return Call("GET", "/v1/mdps", _page, params=_paging(limit, cursor))


def get_mdp(mdp_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/mdps/{id}`."""
    return Call("GET", f"/v1/mdps/{_segment(mdp_id)}", _object)


def delete_mdp(mdp_id: str) -> Call[None]:
    """`DELETE /v1/mdps/{id}`."""
    return Call("DELETE", f"/v1/mdps/{_segment(mdp_id)}", _nothing)


def mdp_arrays(mdp_id: str) -> Call[dict[str, np.ndarray]]:
    """`GET /v1/mdps/{id}/arrays`."""
    return Call("GET", f"/v1/mdps/{_segment(mdp_id)}/arrays", _npz)


# -------------------------------------------------------------- demonstrators, tasks, demonstrations


def create_demonstrator(name: str, metadata: Mapping[str, Any] | None) -> Call[str]:
    """`POST /v1/demonstrators`."""
    body = {"name": name, "metadata": dict(metadata) if metadata is not None else None}
    return Call("POST", "/v1/demonstrators", _id, json=body)


def list_demonstrators(limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/demonstrators`."""
    return Call("GET", "/v1/demonstrators", _page, params=_paging(limit, cursor))


def get_demonstrator(demonstrator_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/demonstrators/{id}`."""
    return Call("GET", f"/v1/demonstrators/{_segment(demonstrator_id)}", _object)


def delete_demonstrator(demonstrator_id: str) -> Call[None]:
    """`DELETE /v1/demonstrators/{id}`."""
    return Call("DELETE", f"/v1/demonstrators/{_segment(demonstrator_id)}", _nothing)


def create_task(
    demonstrator_id: str, name: str, mdp_id: str, metadata: Mapping[str, Any] | None
) -> Call[str]:
    """`POST /v1/demonstrators/{id}/tasks`."""
    body = {"name": name, "mdp_id": mdp_id, "metadata": dict(metadata) if metadata is not None else None}
    return Call("POST", f"/v1/demonstrators/{_segment(demonstrator_id)}/tasks", _id, json=body)


def list_tasks(demonstrator_id: str, limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/demonstrators/{id}/tasks`."""
    path = f"/v1/demonstrators/{_segment(demonstrator_id)}/tasks"
    return Call("GET", path, _page, params=_paging(limit, cursor))


def get_task(task_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/tasks/{id}`."""
    return Call("GET", f"/v1/tasks/{_segment(task_id)}", _object)


def delete_task(task_id: str) -> Call[None]:
    """`DELETE /v1/tasks/{id}`."""
    return Call("DELETE", f"/v1/tasks/{_segment(task_id)}", _nothing)


def put_true_reward(task_id: str, values: np.ndarray | Sequence[float]) -> Call[None]:
    """`PUT /v1/tasks/{id}/true-reward`."""
    body = {"values": np.asarray(values, dtype=np.float64).tolist()}
    return Call("PUT", f"/v1/tasks/{_segment(task_id)}/true-reward", _nothing, json=body)


def get_true_reward(task_id: str) -> Call[np.ndarray]:
    """`GET /v1/tasks/{id}/true-reward?format=npy` as float64, as `reward_values` reads a learned reward."""
    return Call("GET", f"/v1/tasks/{_segment(task_id)}/true-reward", _npy, params={"format": "npy"})


def add_demonstrations(task_id: str, trajectories: Iterable[Trajectory | Mapping[str, Any]]) -> Call[str]:
    """`POST /v1/tasks/{id}/demonstrations` with every trajectory as JSON."""
    body = {
        "trajectories": [
            {"states": s, "actions": a}
            for s, a in (_states_actions(t, i) for i, t in enumerate(trajectories))
        ]
    }
    return Call("POST", f"/v1/tasks/{_segment(task_id)}/demonstrations", _id, json=body)


def upload_demonstrations(task_id: str, file: str | PathLike[str] | bytes) -> Call[str]:
    """`POST /v1/tasks/{id}/demonstrations` with a CSV file (multipart): a path, or the file's bytes."""
    if isinstance(file, bytes):
        content, filename = file, "demonstrations.csv"
    else:
        content, filename = Path(file).read_bytes(), Path(file).name
    files = {"file": (filename, content, "text/csv")}
    return Call("POST", f"/v1/tasks/{_segment(task_id)}/demonstrations", _id, files=files)


def list_demonstrations(task_id: str, limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/tasks/{id}/demonstrations`."""
    path = f"/v1/tasks/{_segment(task_id)}/demonstrations"
    return Call("GET", path, _page, params=_paging(limit, cursor))


def _batch_path(task_id: str, batch_id: str) -> str:
    """The path of one demonstration upload of a task."""
    return f"/v1/tasks/{_segment(task_id)}/demonstrations/{_segment(batch_id)}"


def get_demonstrations(task_id: str, batch_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/tasks/{id}/demonstrations/{batch_id}` as JSON."""
    return Call("GET", _batch_path(task_id, batch_id), _object)


def download_demonstrations(task_id: str, batch_id: str) -> Call[bytes]:
    """`GET /v1/tasks/{id}/demonstrations/{batch_id}?format=csv`."""
    return Call("GET", _batch_path(task_id, batch_id), _content, params={"format": "csv"})


def delete_demonstrations(task_id: str, batch_id: str) -> Call[None]:
    """`DELETE /v1/tasks/{id}/demonstrations/{batch_id}`."""
    return Call("DELETE", _batch_path(task_id, batch_id), _nothing)


# -------------------------------------------------------------- recordings


def upload_recording(
    demonstrator_id: str,
    file: Path | bytes,
    *,
    mdp_id: str | None,
    bounds: Mapping[str, float] | None,
    name: str | None,
    plate: Mapping[str, Any] | None,
    protocol: Protocol,
    metadata: Mapping[str, Any] | None,
    units: str | None,
) -> Call[dict[str, Any]]:
    """`POST /v1/demonstrators/{id}/recordings` with a recording file (multipart)."""
    content = file.read_bytes() if isinstance(file, Path) else file
    filename = file.name if isinstance(file, Path) else "recording"
    form = {"protocol": protocol} | ({"mdp_id": mdp_id} if mdp_id else {})
    form |= {"bounds": json.dumps(dict(bounds))} if bounds else {}
    form |= ({"name": name} if name else {}) | ({"plate": json.dumps(dict(plate))} if plate else {})
    form |= {"metadata": json.dumps(dict(metadata))} if metadata else {}
    form |= {"units": units} if units is not None else {}
    files = {"file": (filename, content, "application/octet-stream")}
    path = f"/v1/demonstrators/{_segment(demonstrator_id)}/recordings"
    return Call("POST", path, _object, files=files, data=form)


def list_recordings(demonstrator_id: str, limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/demonstrators/{id}/recordings`."""
    path = f"/v1/demonstrators/{_segment(demonstrator_id)}/recordings"
    return Call("GET", path, _page, params=_paging(limit, cursor))


def recording_demonstrations(recording_id: str, label: str | None) -> Call[dict[str, Any]]:
    """`GET /v1/recordings/{id}/demonstrations` as JSON."""
    params = {"label": label} if label is not None else None
    return Call("GET", f"/v1/recordings/{_segment(recording_id)}/demonstrations", _object, params=params)


def recording_sway(
    recording_id: str, *, lowpass_hz: float | None, trim_start_s: float, trim_end_s: float, spectra: bool
) -> Call[dict[str, Any]]:
    """`GET /v1/recordings/{id}/sway`: the posturography measures of a recording's COP."""
    params = _sway_params(lowpass_hz, trim_start_s, trim_end_s) | ({"spectra": "true"} if spectra else {})
    return Call("GET", f"/v1/recordings/{_segment(recording_id)}/sway", _object, params=params)


def recording_sway_png(
    recording_id: str, *, lowpass_hz: float | None, trim_start_s: float, trim_end_s: float
) -> Call[bytes]:
    """`GET /v1/recordings/{id}/sway?format=png`: the COP path with its 95 % ellipse."""
    params = _sway_params(lowpass_hz, trim_start_s, trim_end_s) | {"format": "png"}
    return Call("GET", f"/v1/recordings/{_segment(recording_id)}/sway", _content, params=params)


def sway_summary(demonstrator_id: str, by: str) -> Call[dict[str, Any]]:
    """`GET /v1/demonstrators/{id}/sway-summary?by=label`: standing trials grouped by a metadata label."""
    path = f"/v1/demonstrators/{_segment(demonstrator_id)}/sway-summary"
    return Call("GET", path, _object, params={"by": by})


def _sway_params(lowpass_hz: float | None, trim_start_s: float, trim_end_s: float) -> dict[str, str]:
    """The sway route's options, sent only when set (the route's defaults: unfiltered, untrimmed)."""
    params = {"lowpass_hz": str(lowpass_hz)} if lowpass_hz is not None else {}
    params |= {"trim_start_s": str(trim_start_s)} if trim_start_s else {}
    return params | ({"trim_end_s": str(trim_end_s)} if trim_end_s else {})


# -------------------------------------------------------------- jobs


def submit_job(
    demonstrator_id: str, task_ids: Sequence[str] | None, config: Mapping[str, Any] | None
) -> Call[JobState]:
    """`POST /v1/jobs`."""
    body: dict[str, Any] = {"demonstrator_id": demonstrator_id, "config": dict(config) if config else None}
    if task_ids is not None:
        body["task_ids"] = [task_ids] if isinstance(task_ids, str) else list(task_ids)  # one id, or several
    return Call("POST", "/v1/jobs", _job, json=body)


def list_jobs(
    status: JobStatusName | None, demonstrator_id: str | None, limit: int | None, cursor: str | None
) -> Call[Page]:
    """`GET /v1/jobs`, filtered by status and demonstrator."""
    params = _paging(limit, cursor, status=status, demonstrator_id=demonstrator_id)
    return Call("GET", "/v1/jobs", _page, params=params)


def get_job(job_id: str) -> Call[JobState]:
    """`GET /v1/jobs/{id}` as a `JobState`."""
    return Call("GET", f"/v1/jobs/{_segment(job_id)}", _job)


def delete_job(job_id: str) -> Call[None]:
    """`DELETE /v1/jobs/{id}`."""
    return Call("DELETE", f"/v1/jobs/{_segment(job_id)}", _nothing)


def cancel_job(job_id: str) -> Call[JobState]:
    """`POST /v1/jobs/{id}/cancel`."""
    return Call("POST", f"/v1/jobs/{_segment(job_id)}/cancel", _job)


def list_events(job_id: str, limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/jobs/{id}/events` as JSON pages (the stream is `Client.wait`'s)."""
    return Call("GET", events_path(job_id), _page, params=_paging(limit, cursor))


def job_history(job_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/jobs/{id}/history`."""
    return Call("GET", f"/v1/jobs/{_segment(job_id)}/history", _object)


def events_path(job_id: str) -> str:
    """The path of a job's events."""
    return f"/v1/jobs/{_segment(job_id)}/events"


# -------------------------------------------------------------- results


def job_rewards(job_id: str, exclude_top_truth: bool) -> Call[JobRewardIds]:
    """`GET /v1/jobs/{id}/rewards`."""
    params = {"exclude_top_truth": "true"} if exclude_top_truth else None
    return Call("GET", f"/v1/jobs/{_segment(job_id)}/rewards", _rewards, params=params)


def _reward_params(format: RewardFormat, quantity: Quantity, overlay: bool) -> dict[str, str]:
    """Query parameters of a reward download."""
    return {"format": format, "quantity": quantity} | ({"overlay": "demos"} if overlay else {})


def reward_values(reward_id: str, quantity: Quantity) -> Call[np.ndarray]:
    """`GET /v1/rewards/{id}?format=npy` as float64."""
    params = _reward_params("npy", quantity, overlay=False)
    return Call("GET", f"/v1/rewards/{_segment(reward_id)}", _npy, params=params)


def download_reward(reward_id: str, format: RewardFormat, quantity: Quantity, overlay: bool) -> Call[bytes]:
    """`GET /v1/rewards/{id}?format=…` as the raw bytes."""
    params = _reward_params(format, quantity, overlay)
    return Call("GET", f"/v1/rewards/{_segment(reward_id)}", _content, params=params)


def compare(
    reward_id: str, other: str | Sequence[float] | np.ndarray, states: str, other_is_task: bool
) -> Call[dict[str, Any]]:
    """`POST /v1/comparisons`."""
    if isinstance(other, str):
        b: dict[str, Any] = {"task_id": other} if other_is_task else {"reward_id": other}
    else:
        b = {"values": np.asarray(other, dtype=np.float64).tolist()}
    body = {"a": {"reward_id": reward_id}, "b": b, "states": states}
    return Call("POST", "/v1/comparisons", _object, json=body)


def comparison_matrix(job_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/jobs/{id}/comparison-matrix` as JSON."""
    return Call("GET", f"/v1/jobs/{_segment(job_id)}/comparison-matrix", _object)


def comparison_matrix_png(job_id: str) -> Call[bytes]:
    """`GET /v1/jobs/{id}/comparison-matrix?format=png`."""
    path = f"/v1/jobs/{_segment(job_id)}/comparison-matrix"
    return Call("GET", path, _content, params={"format": "png"})


def key_states(reward_id: str, top: int) -> Call[dict[str, Any]]:
    """`GET /v1/rewards/{id}/key-states?top=k`."""
    return Call("GET", f"/v1/rewards/{_segment(reward_id)}/key-states", _object, params={"top": top})


# -------------------------------------------------------------- motion


def motion_summary(demonstrator_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/demonstrators/{id}/motion-summary`."""
    return Call("GET", f"/v1/demonstrators/{_segment(demonstrator_id)}/motion-summary", _object)


def compare_motion(a: str, b: str) -> Call[dict[str, Any]]:
    """`POST /v1/motion-comparisons` as JSON."""
    return Call("POST", "/v1/motion-comparisons", _object, json={"a": a, "b": b})


def compare_motion_png(a: str, b: str) -> Call[bytes]:
    """`POST /v1/motion-comparisons?format=png`."""
    return Call("POST", "/v1/motion-comparisons", _content, params={"format": "png"}, json={"a": a, "b": b})


# -------------------------------------------------------------- webhooks


def create_webhook(url: str, events: Sequence[WebhookEvent] | None) -> Call[dict[str, Any]]:
    """`POST /v1/webhooks`."""
    body: dict[str, Any] = {"url": url} | ({"events": list(events)} if events is not None else {})
    return Call("POST", "/v1/webhooks", _object, json=body)


def list_webhooks(limit: int | None, cursor: str | None) -> Call[Page]:
    """`GET /v1/webhooks`."""
    return Call("GET", "/v1/webhooks", _page, params=_paging(limit, cursor))


def get_webhook(webhook_id: str) -> Call[dict[str, Any]]:
    """`GET /v1/webhooks/{id}`."""
    return Call("GET", f"/v1/webhooks/{_segment(webhook_id)}", _object)


def delete_webhook(webhook_id: str) -> Call[None]:
    """`DELETE /v1/webhooks/{id}`."""
    return Call("DELETE", f"/v1/webhooks/{_segment(webhook_id)}", _nothing)
