"""`Client`, the synchronous lab client: one typed method per API operation (docs/client.md).

Each method builds its `Call` in `_operations` and sends it through `_transport.send`, the one place that
retries and turns an error answer into the `MetairlError` subclass of its status."""

from __future__ import annotations

import contextlib
import copy
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from os import PathLike
from pathlib import Path
from types import TracebackType
from typing import IO, Any, TypeVar

import httpx
import numpy as np

from metairl_client import _operations as ops
from metairl_client._errors import error_from_response
from metairl_client._models import JobRewardIds, JobState, Page, Trajectory
from metairl_client._operations import JobStatusName, Protocol, Quantity, RewardFormat, WebhookEvent
from metairl_client._sse import events, is_event_stream
from metairl_client._transport import Call, Retries, Timeout, UseClientDefault, send
from metairl_client._version import __version__
from metairl_client._waiting import STREAM_FAILURES, NoStream, Waiter

T = TypeVar("T")

DEFAULT_TIMEOUT_S = 60.0


def checked_url(url: str) -> str:
    """The service's base URL without a trailing slash; `ValueError` for one without ``http://`` or ``https://``
    (``127.0.0.1:8000``), which httpx would only refuse at the first request, as if the service were down."""
    try:
        scheme = httpx.URL(url).scheme
    except httpx.InvalidURL as error:
        raise ValueError(f"not a URL: {url!r} ({error})") from error
    if scheme not in ("http", "https"):
        raise ValueError(
            f"the service URL must start with http:// or https:// (as `metairl serve` prints it): {url!r}"
        )
    return url.rstrip("/")


def client_headers(api_key: str | None) -> dict[str, str]:
    """The headers every request of a client made from a URL carries."""
    auth = {"Authorization": f"Bearer {api_key}"} if api_key else {}
    return {"User-Agent": f"metairl-client/{__version__}"} | auth


class Client:
    """A lab's connection to a metairl service: ``Client(url, api_key)``, or ``Client(http)`` around an
    `httpx.Client` that already carries base URL and key. Use it as a context manager to close it."""

    def __init__(
        self,
        url: str | httpx.Client,
        api_key: str | None = None,
        *,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        max_retries: int = Retries.max_retries,
    ):
        if isinstance(url, str):
            url = checked_url(url)
            self.http = httpx.Client(base_url=url, headers=client_headers(api_key), timeout=timeout_s)
        else:
            self.http = url
        self.retries = Retries(max_retries=max_retries)
        self.timeout: Timeout = httpx.USE_CLIENT_DEFAULT

    @classmethod
    def connect(
        cls,
        *,
        url: str,
        api_key: str,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        max_retries: int = Retries.max_retries,
    ) -> Client:
        """A client of the service at ``url`` authenticating with ``api_key`` (Bearer)."""
        return cls(url, api_key, timeout_s=timeout_s, max_retries=max_retries)

    def with_options(self, *, max_retries: int | None = None, timeout_s: float | None = None) -> Client:
        """A client on the same connections with other retries or timeout (per request), e.g.
        ``lab.with_options(max_retries=5).get_job(job_id)``."""
        other = copy.copy(self)
        if max_retries is not None:
            other.retries = Retries(max_retries=max_retries)
        if timeout_s is not None:
            other.timeout = timeout_s
        return other

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the underlying HTTP connections."""
        self.http.close()

    def _call(self, call: Call[T]) -> T:
        """Send one call (with retries) and read its answer."""
        return send(self.http, call, self.retries, self.timeout)

    def _pages(self, page: Callable[[str | None], Call[Page]]) -> Iterator[dict[str, Any]]:
        """Every item of a list, fetching page after page as the iteration reaches it."""
        cursor: str | None = None
        while True:
            current = self._call(page(cursor))
            yield from current.data
            if not (current.has_more and current.next_cursor):
                return
            cursor = current.next_cursor

    # -------------------------------------------------------------- service

    def check_health(self) -> None:
        """`GET /healthz`: fails early, with a clear error, when nothing answers at the URL."""
        self._call(ops.health())

    def check_ready(self) -> dict[str, Any]:
        """`GET /readyz`: whether the service can serve (database reachable); `ServiceUnavailableError` if not."""
        return self._call(ops.readiness())

    # -------------------------------------------------------------- MDPs

    def create_mdp(self, body: Mapping[str, Any]) -> str:
        """`POST /v1/mdps` with an explicit or grid MDP body; returns the MDP id."""
        return self._call(ops.create_mdp(body))

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
        call = ops.upload_mdp(
            name=name, gamma=gamma, arrays=arrays, layout=layout, n_states=n_states, n_actions=n_actions
        )
        return self._call(call)

    def list_mdps(self, *, limit: int | None = None, cursor: str | None = None) -> Page:
        """`GET /v1/mdps`: one page of the lab's MDPs."""
        return self._call(ops.list_mdps(limit, cursor))

    def iter_mdps(self, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every MDP of the lab, page after page."""
        return self._pages(lambda cursor: ops.list_mdps(page_size, cursor))

    def get_mdp(self, mdp_id: str) -> dict[str, Any]:
        """`GET /v1/mdps/{id}`: the MDP resource (``n_states``, ``n_actions``, ``gamma``, checksums, …)."""
        return self._call(ops.get_mdp(mdp_id))

    def delete_mdp(self, mdp_id: str) -> None:
        """`DELETE /v1/mdps/{id}` (`ConflictError` while a task uses it)."""
        self._call(ops.delete_mdp(mdp_id))

    def mdp_arrays(self, mdp_id: str) -> dict[str, np.ndarray]:
        """`GET /v1/mdps/{id}/arrays`: the MDP's arrays under the names `upload_mdp` takes."""
        return self._call(ops.mdp_arrays(mdp_id))

    # -------------------------------------------------------------- demonstrators, tasks, demonstrations

    def create_demonstrator(self, *, name: str, metadata: Mapping[str, Any] | None = None) -> str:
        """`POST /v1/demonstrators`; returns the demonstrator id."""
        return self._call(ops.create_demonstrator(name, metadata))

    def list_demonstrators(self, *, limit: int | None = None, cursor: str | None = None) -> Page:
        """`GET /v1/demonstrators`: one page of the lab's demonstrators."""
        return self._call(ops.list_demonstrators(limit, cursor))

    def iter_demonstrators(self, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every demonstrator of the lab, page after page."""
        return self._pages(lambda cursor: ops.list_demonstrators(page_size, cursor))

    def get_demonstrator(self, demonstrator_id: str) -> dict[str, Any]:
        """`GET /v1/demonstrators/{id}`."""
        return self._call(ops.get_demonstrator(demonstrator_id))

    def delete_demonstrator(self, demonstrator_id: str) -> None:
        """`DELETE /v1/demonstrators/{id}` with its tasks, recordings, jobs and rewards."""
        self._call(ops.delete_demonstrator(demonstrator_id))

    def create_task(
        self, demonstrator_id: str, *, name: str, mdp_id: str, metadata: Mapping[str, Any] | None = None
    ) -> str:
        """`POST /v1/demonstrators/{id}/tasks`; returns the task id."""
        return self._call(ops.create_task(demonstrator_id, name, mdp_id, metadata))

    def list_tasks(
        self, demonstrator_id: str, *, limit: int | None = None, cursor: str | None = None
    ) -> Page:
        """`GET /v1/demonstrators/{id}/tasks`: one page of the demonstrator's tasks."""
        return self._call(ops.list_tasks(demonstrator_id, limit, cursor))

    def iter_tasks(self, demonstrator_id: str, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every task of the demonstrator, page after page."""
        return self._pages(lambda cursor: ops.list_tasks(demonstrator_id, page_size, cursor))

    def get_task(self, task_id: str) -> dict[str, Any]:
        """`GET /v1/tasks/{id}`."""
        return self._call(ops.get_task(task_id))

    def delete_task(self, task_id: str) -> None:
        """`DELETE /v1/tasks/{id}` with its demonstrations."""
        self._call(ops.delete_task(task_id))

    def put_true_reward(self, task_id: str, values: np.ndarray | Sequence[float]) -> None:
        """`PUT /v1/tasks/{id}/true-reward`: the simulation's ground truth, one value per state."""
        self._call(ops.put_true_reward(task_id, values))

    def get_true_reward(self, task_id: str) -> np.ndarray:
        """`GET /v1/tasks/{id}/true-reward?format=npy`: the stored ground truth as float64, one value per state,
        as `reward_values` gives a learned reward (`NotFoundError` when none was set)."""
        return self._call(ops.get_true_reward(task_id))

    def add_demonstrations(self, task_id: str, trajectories: Iterable[Trajectory | Mapping[str, Any]]) -> str:
        """`POST /v1/tasks/{id}/demonstrations` with every trajectory, given as objects with ``states`` and
        ``actions``, as (states, actions) pairs of integer arrays or as the API's ``{"states": …, "actions":
        …}`` (floats that are whole numbers, as ``np.loadtxt`` gives, are sent as integers). Returns the upload
        batch's id; `InvalidRequestError`, nothing sent, for a trajectory of another shape."""
        return self._call(ops.add_demonstrations(task_id, trajectories))

    def list_demonstrations(
        self, task_id: str, *, limit: int | None = None, cursor: str | None = None
    ) -> Page:
        """`GET /v1/tasks/{id}/demonstrations`: one page of the task's demonstrations."""
        return self._call(ops.list_demonstrations(task_id, limit, cursor))

    def iter_demonstrations(self, task_id: str, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every demonstration of the task, page after page."""
        return self._pages(lambda cursor: ops.list_demonstrations(task_id, page_size, cursor))

    def upload_demonstrations(self, task_id: str, file: str | PathLike[str] | bytes) -> str:
        """`POST /v1/tasks/{id}/demonstrations` with a CSV file of columns ``trajectory,step,state,action`` (the
        final state's row may leave ``action`` empty), given as a path or as the file's bytes. Returns the upload
        batch's id; errors name the trajectory label and the CSV line."""
        return self._call(ops.upload_demonstrations(task_id, file))

    def get_demonstrations(self, task_id: str, batch_id: str) -> dict[str, Any]:
        """`GET /v1/tasks/{id}/demonstrations/{batch_id}`: one upload batch (``n_trajectories``, ``format``, …)
        with its ``trajectories`` as ``{"states": […], "actions": […]}``, which `add_demonstrations` takes back."""
        return self._call(ops.get_demonstrations(task_id, batch_id))

    def download_demonstrations(self, task_id: str, batch_id: str) -> bytes:
        """`GET /v1/tasks/{id}/demonstrations/{batch_id}?format=csv`: the batch as the CSV
        `upload_demonstrations` takes."""
        return self._call(ops.download_demonstrations(task_id, batch_id))

    def delete_demonstrations(self, task_id: str, batch_id: str) -> None:
        """`DELETE /v1/tasks/{id}/demonstrations/{batch_id}` with the task's jobs that finished after it was
        uploaded (`ConflictError` while a job on the task is queued or running)."""
        self._call(ops.delete_demonstrations(task_id, batch_id))

    # -------------------------------------------------------------- recordings

    def upload_recording(
        self,
        demonstrator_id: str,
        file: Path | bytes,
        *,
        mdp_id: str | None = None,
        bounds: Mapping[str, float] | None = None,
        name: str | None = None,
        plate: Mapping[str, Any] | None = None,
        protocol: Protocol = "movements",
        metadata: Mapping[str, Any] | None = None,
        units: str | None = None,
    ) -> dict[str, Any]:
        """`POST /v1/demonstrators/{id}/recordings` with a recording file: a CSV of centre-of-pressure samples
        (``t,x,y`` and optionally ``instruction``), a C3D file, or a CSV of plate forces and moments (``plate``
        says how to read a force-plate file; docs/motion.md). ``protocol="movements"`` cuts out-and-back
        movements onto the velocity grid ``mdp_id`` within ``bounds`` (``x_min``, ``x_max``, ``y_min``,
        ``y_max``); ``"standing"`` stores a quiet-standing trial whole, labelled by ``metadata`` (e.g.
        ``{"vision": "closed"}``). ``units`` is the length unit of the COP samples (e.g. ``"cm"``; a CSV header
        such as ``COPx[cm]`` may give it instead; a force-plate file's must be the file's own or ``"m"``). Returns the
        recording."""
        return self._call(
            ops.upload_recording(
                demonstrator_id,
                file,
                mdp_id=mdp_id,
                bounds=bounds,
                name=name,
                plate=plate,
                protocol=protocol,
                metadata=metadata,
                units=units,
            )
        )

    def list_recordings(
        self, demonstrator_id: str, *, limit: int | None = None, cursor: str | None = None
    ) -> Page:
        """`GET /v1/demonstrators/{id}/recordings`: one page of the demonstrator's recordings."""
        return self._call(ops.list_recordings(demonstrator_id, limit, cursor))

    def iter_recordings(self, demonstrator_id: str, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every recording of the demonstrator, page after page."""
        return self._pages(lambda cursor: ops.list_recordings(demonstrator_id, page_size, cursor))

    def recording_demonstrations(self, recording_id: str, *, label: str | None = None) -> dict[str, Any]:
        """`GET /v1/recordings/{id}/demonstrations`: the trajectories cut from a recording (one label's)."""
        return self._call(ops.recording_demonstrations(recording_id, label))

    # -------------------------------------------------------------- jobs

    def submit_job(
        self,
        demonstrator_id: str,
        *,
        task_ids: Sequence[str] | None = None,
        config: Mapping[str, Any] | None = None,
    ) -> JobState:
        """`POST /v1/jobs` (202): fit the demonstrator's tasks (all unless ``task_ids``); the new job's state."""
        return self._call(ops.submit_job(demonstrator_id, task_ids, config))

    def list_jobs(
        self,
        *,
        status: JobStatusName | None = None,
        demonstrator_id: str | None = None,
        limit: int | None = None,
        cursor: str | None = None,
    ) -> Page:
        """`GET /v1/jobs`: one page of the lab's jobs, filtered by status and demonstrator."""
        return self._call(ops.list_jobs(status, demonstrator_id, limit, cursor))

    def iter_jobs(
        self, *, status: JobStatusName | None = None, demonstrator_id: str | None = None, page_size: int = 100
    ) -> Iterator[dict[str, Any]]:
        """Every job of the lab (filtered by status and demonstrator), page after page."""
        return self._pages(lambda cursor: ops.list_jobs(status, demonstrator_id, page_size, cursor))

    def get_job(self, job_id: str) -> JobState:
        """`GET /v1/jobs/{id}`: status and progress."""
        return self._call(ops.get_job(job_id))

    def delete_job(self, job_id: str) -> None:
        """`DELETE /v1/jobs/{id}` with its events and rewards (`ConflictError` while queued or running)."""
        self._call(ops.delete_job(job_id))

    def cancel_job(self, job_id: str) -> JobState:
        """`POST /v1/jobs/{id}/cancel`: a queued job is cancelled at once, a running one within seconds;
        the job's state (`ConflictError` when it already finished)."""
        return self._call(ops.cancel_job(job_id))

    def list_events(self, job_id: str, *, limit: int | None = None, cursor: str | None = None) -> Page:
        """`GET /v1/jobs/{id}/events`: one page of the job's progress log and status changes."""
        return self._call(ops.list_events(job_id, limit, cursor))

    def job_history(self, job_id: str) -> dict[str, Any]:
        """`GET /v1/jobs/{id}/history`: the loss curve (loss, IRL and sharing losses, held-out NLL by step):
        every step once the job has succeeded (`source` "steps"), else the latest attempt's progress samples
        ("samples")."""
        return self._call(ops.job_history(job_id))

    def iter_events(self, job_id: str, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every stored event of the job, page after page (`wait` follows them live)."""
        return self._pages(lambda cursor: ops.list_events(job_id, page_size, cursor))

    def wait(
        self,
        job_id: str,
        *,
        poll_s: float = 0.5,
        timeout_s: float | None = None,
        progress: bool = True,
        stream: IO[str] | None = None,
    ) -> JobState:
        """Follow the job until it succeeds, fails or is cancelled, with a tqdm bar on ``stream`` (stderr by
        default; none if ``progress`` is false). Returns the final state; `TimeoutError` after ``timeout_s``.
        A failed job is returned, not raised: its ``error`` says what to change.

        The job's events arrive as Server-Sent Events (one connection, resumed with ``Last-Event-ID`` if
        it drops); a server without the stream is polled every ``poll_s`` instead."""
        with Waiter(job_id, timeout_s=timeout_s, progress=progress, stream=stream) as waiter:
            waiter.show(self.get_job(job_id))
            if not waiter.finished:
                with contextlib.suppress(NoStream):
                    self._follow(waiter)
            while not waiter.finished:
                waiter.check_deadline()
                time.sleep(waiter.pause(poll_s))
                waiter.show(self.get_job(job_id))
            return waiter.current

    def _stream_timeout(self) -> httpx.Timeout:
        """This client's timeout (`with_options` included) as an `httpx.Timeout`."""
        if isinstance(self.timeout, UseClientDefault):
            return self.http.timeout
        return httpx.Timeout(self.timeout)

    def _follow(self, waiter: Waiter) -> None:
        """Read the job's event stream until its final status, reconnecting after the last event seen;
        `NoStream` when the server does not stream, refuses a stream for now (429, 503), the connection keeps
        failing or the deadline is near; `TimeoutError` past the deadline, quiet stream or not."""
        path = ops.events_path(waiter.job_id)
        failures = 0
        while True:
            waiter.tick()
            timeout = waiter.stream_timeout(self._stream_timeout())
            headers = waiter.stream_headers()
            try:
                with self.http.stream("GET", path, headers=headers, timeout=timeout) as response:
                    if response.is_error:
                        response.read()
                        if waiter.refuses_stream(response):
                            raise NoStream
                        raise error_from_response(response)
                    if not is_event_stream(response):
                        raise NoStream
                    for event_id, kind, data in events(response, waiter.tick):
                        failures = 0
                        if waiter.on_event(event_id, kind, data):
                            waiter.show(self.get_job(waiter.job_id))  # the final row: error, last progress
                            return
            except httpx.TransportError as exc:
                waiter.check_deadline()
                failures += 1
                if failures > STREAM_FAILURES:
                    raise NoStream from exc
                time.sleep(waiter.pause(0.5 * failures))
            waiter.check_deadline()
            waiter.show(self.get_job(waiter.job_id))  # the stream ended (its time limit, or a drop)
            if waiter.finished:
                return

    # -------------------------------------------------------------- results

    def job_rewards(self, job_id: str, *, exclude_top_truth: bool = False) -> JobRewardIds:
        """`GET /v1/jobs/{id}/rewards`: reward ids of the baseline and of every task (`ConflictError` before
        the job succeeded); ``exclude_top_truth`` adds truth scores without the goal states."""
        return self._call(ops.job_rewards(job_id, exclude_top_truth))

    def reward_values(self, reward_id: str, *, quantity: Quantity = "reward") -> np.ndarray:
        """`GET /v1/rewards/{id}?format=npy`: a reward as float64; or a task's ``value`` or ``policy``, or any
        reward's ``uncertainty`` (its spread across the ensemble) or ``evidence`` (1 demonstrated, 0.5 one move
        away, 0)."""
        return self._call(ops.reward_values(reward_id, quantity))

    def download_reward(
        self,
        reward_id: str,
        *,
        format: RewardFormat = "json",
        quantity: Quantity = "reward",
        overlay: bool = False,
    ) -> bytes:
        """`GET /v1/rewards/{id}?format=…`: a reward, value function, policy, uncertainty or evidence in
        any format, as bytes (``overlay`` draws the demonstrations on a PNG)."""
        return self._call(ops.download_reward(reward_id, format, quantity, overlay))

    def reward_png(self, reward_id: str) -> bytes:
        """`GET /v1/rewards/{id}?format=png`: the reward as a heatmap (an MDP with a grid layout)."""
        return self.download_reward(reward_id, format="png")

    def rewards(self, job_id: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """A succeeded job's learned rewards: the baseline, and each task's keyed by task id."""
        ids = self.job_rewards(job_id)
        return self.reward_values(ids.baseline), {t: self.reward_values(r) for t, r in ids.tasks.items()}

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
        ``visited`` ones. Returns the comparison (``pearson``, ``spearman``, ``epic_distance``, …)."""
        return self._call(ops.compare(reward_id, other, states, other_is_task))

    def comparison_matrix(self, job_id: str) -> dict[str, Any]:
        """`GET /v1/jobs/{id}/comparison-matrix`: pairwise Pearson of the job's rewards."""
        return self._call(ops.comparison_matrix(job_id))

    def comparison_matrix_png(self, job_id: str) -> bytes:
        """`GET /v1/jobs/{id}/comparison-matrix?format=png`: the matrix drawn as a PNG."""
        return self._call(ops.comparison_matrix_png(job_id))

    def key_states(self, reward_id: str, *, top: int = 10) -> dict[str, Any]:
        """`GET /v1/rewards/{id}/key-states`: the ``top`` states where a task reward departs most from its
        baseline."""
        return self._call(ops.key_states(reward_id, top))

    # -------------------------------------------------------------- motion

    def motion_summary(self, demonstrator_id: str) -> dict[str, Any]:
        """`GET /v1/demonstrators/{id}/motion-summary`: per direction, reach and path descriptors with
        intervals, and the learned readout (`ConflictError` without recordings)."""
        return self._call(ops.motion_summary(demonstrator_id))

    def compare_motion(self, a: str, b: str) -> dict[str, Any]:
        """`POST /v1/motion-comparisons`: demonstrator ``b`` minus ``a``, per direction."""
        return self._call(ops.compare_motion(a, b))

    def compare_motion_png(self, a: str, b: str) -> bytes:
        """`POST /v1/motion-comparisons?format=png`: the comparison drawn."""
        return self._call(ops.compare_motion_png(a, b))

    def recording_sway(
        self,
        recording_id: str,
        *,
        lowpass_hz: float | None = None,
        trim_start_s: float = 0.0,
        trim_end_s: float = 0.0,
        spectra: bool = False,
    ) -> dict[str, Any]:
        """`GET /v1/recordings/{id}/sway`: path length, velocity, ellipse area, frequencies… of the COP, unfiltered
        and untrimmed unless asked (``spectra``: the Welch spectra too)."""
        return self._call(
            ops.recording_sway(
                recording_id,
                lowpass_hz=lowpass_hz,
                trim_start_s=trim_start_s,
                trim_end_s=trim_end_s,
                spectra=spectra,
            )
        )

    def recording_sway_png(
        self,
        recording_id: str,
        *,
        lowpass_hz: float | None = None,
        trim_start_s: float = 0.0,
        trim_end_s: float = 0.0,
    ) -> bytes:
        """`GET /v1/recordings/{id}/sway?format=png`: the COP path with its 95 % prediction ellipse."""
        return self._call(
            ops.recording_sway_png(
                recording_id, lowpass_hz=lowpass_hz, trim_start_s=trim_start_s, trim_end_s=trim_end_s
            )
        )

    def sway_summary(self, demonstrator_id: str, *, by: str) -> dict[str, Any]:
        """`GET /v1/demonstrators/{id}/sway-summary?by=label`: standing trials grouped by a metadata label, each
        measure's mean with a 95 % interval per group and the differences between groups."""
        return self._call(ops.sway_summary(demonstrator_id, by))

    # -------------------------------------------------------------- webhooks

    def create_webhook(self, url: str, *, events: Sequence[WebhookEvent] | None = None) -> dict[str, Any]:
        """`POST /v1/webhooks`: the webhook with its signing ``secret`` (shown this once)."""
        return self._call(ops.create_webhook(url, events))

    def list_webhooks(self, *, limit: int | None = None, cursor: str | None = None) -> Page:
        """`GET /v1/webhooks`: one page of the lab's webhooks."""
        return self._call(ops.list_webhooks(limit, cursor))

    def iter_webhooks(self, *, page_size: int = 100) -> Iterator[dict[str, Any]]:
        """Every webhook of the lab, page after page."""
        return self._pages(lambda cursor: ops.list_webhooks(page_size, cursor))

    def get_webhook(self, webhook_id: str) -> dict[str, Any]:
        """`GET /v1/webhooks/{id}` with its recent deliveries."""
        return self._call(ops.get_webhook(webhook_id))

    def delete_webhook(self, webhook_id: str) -> None:
        """`DELETE /v1/webhooks/{id}`."""
        self._call(ops.delete_webhook(webhook_id))
