"""Reliability figure: a worker is SIGKILLed in the middle of a job, and the job still succeeds once.

Starts the real service pieces in a temporary data folder — ``metairl keys create``, the API under
uvicorn and ``metairl worker`` processes, on the embedded SQLite database and ``filesystem://`` broker
unless ``--broker`` names another one — with the heartbeat, stale cutoff and reaper interval shortened
by their ``METAIRL_*`` settings, as the job tests do. It uploads a small grid MDP and a demonstrator with
three tasks over HTTP, submits a job, and polls ``GET /v1/jobs/{id}`` and its event log every 0.2 s.
When attempt 1 is well under way it SIGKILLs the worker's whole process group, starts a fresh worker,
and keeps polling until the job succeeded: the new worker's reaper finds the stale heartbeat and
re-queues the job, and attempt 2 runs it from step 0 to the end. The timeline (progress per attempt,
status bands, the kill and recovery) is saved as a PNG and summarised on stdout. Usage::

    python -m benchmarks.reliability [--out docs/reliability.png] [--broker redis://127.0.0.1:6379/0]

Nothing is written into the repository but the PNG; the run's data folder is removed at the end, and
with ``--broker`` the run's queue and exchange are deleted. On Redis the killed worker's unacknowledged
message stays in kombu's ``unacked`` table until the visibility timeout, as after any real crash.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from metairl_cli.serve import child_environment, shut_down, spawn, wait_healthy
from metairl_client import TERMINAL_STATUSES, Client, MetairlError
from metairl_engine import Trajectory
from service.jobs.broker import broker_url, delete_queue
from service.settings import Settings

ROOT = Path(__file__).resolve().parents[1]

TIMINGS = {
    "job_heartbeat_s": 0.3,
    "job_stale_after_s": 3.0,
    "reaper_interval_s": 1.0,
    "job_event_interval_s": 0.5,
}
"""Job lifecycle settings shortened as in the job tests (production: 1 s, 60 s, 15 s, 5 s)."""

SIZE = 8
"""Side of the grid MDP (SIZE × SIZE states, 4 moves): small enough for a busy two-core machine."""

CONFIG: dict[str, Any] = {"sharing": "huber", "hidden": [32, 16], "tolerance": 0, "patience": 0, "seed": 0}
"""The job's fit settings besides ``max_steps``: no early stop, so it runs all its steps."""

POLL_S = 0.2
KILL_AT = 0.4
"""Attempt 1 is killed once its reported step reaches this fraction of ``max_steps``."""

RESTART_AFTER_S = 2.0
"""Seconds between the kill and starting the replacement worker."""

WORKER_READY_S = 60.0
STATUS_COLOURS = {"queued": "#f4c26b", "running": "#8ec3e6", "succeeded": "#90d490"}
ATTEMPT_COLOURS = ["#1f5fa8", "#d9541e", "#6a3d9a"]


class RunFailed(RuntimeError):
    """The demonstration did not get to a succeeded job; the text says where it stopped."""


@dataclass(frozen=True)
class Mark:
    """Something this script did, at ``t`` seconds since submission."""

    t: float
    label: str


@dataclass(frozen=True)
class Poll:
    """One ``GET /v1/jobs/{id}``: when, the status, the progress step shown, and the attempts started."""

    t: float
    status: str
    step: int | None
    attempts: int


@dataclass
class Timeline:
    """What the API told about the job: every poll, and its event log by event id."""

    submitted_at: datetime
    polls: list[Poll] = field(default_factory=list)
    events: dict[int, dict[str, Any]] = field(default_factory=dict)

    def since(self, at: datetime | str) -> float:
        """Seconds from submission to ``at`` (a datetime or an ISO timestamp of the API)."""
        moment = datetime.fromisoformat(at) if isinstance(at, str) else at
        return (moment - self.submitted_at).total_seconds()

    def now(self) -> float:
        """Seconds since submission by this machine's clock (the one the service's timestamps come from)."""
        return self.since(datetime.now(UTC))

    def mark(self, label: str) -> Mark:
        """A mark of ``label`` happening now."""
        return Mark(self.now(), label)

    def status_events(self) -> list[dict[str, Any]]:
        """The status changes of the log, oldest first."""
        return [e for _, e in sorted(self.events.items()) if e["kind"] == "status"]

    def requeued(self) -> dict[str, Any]:
        """The reaper's status change back to ``queued`` (the first ``queued`` after attempt 0)."""
        return next(e for e in self.status_events() if e["status"] == "queued" and e["attempt"] >= 1)

    def progress(self, attempt: int) -> tuple[list[float], list[int]]:
        """Times and steps of one attempt's progress samples in the log."""
        mine = [
            e for _, e in sorted(self.events.items()) if e["kind"] == "progress" and e["attempt"] == attempt
        ]
        return [self.since(e["at"]) for e in mine], [int(e["step"]) for e in mine]


@dataclass
class Worker:
    """One ``metairl worker`` process in its own session (so its whole pool dies with one killpg), and its log."""

    process: subprocess.Popen[bytes]
    log: Path

    @classmethod
    def start(cls, env: dict[str, str], log: Path) -> Worker:
        """Start a worker with one job slot; returns at once (see `ready`)."""
        with open(log, "wb") as out:
            process = subprocess.Popen(
                [sys.executable, "-m", "metairl_cli.main", "worker", "--concurrency", "1"],
                cwd=ROOT,
                env=env,
                stdout=out,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        return cls(process, log)

    def ready(self) -> bool:
        """Whether Celery reported the worker ready; `RunFailed` if it exited."""
        if self.process.poll() is not None:
            raise RunFailed(f"a worker exited with code {self.process.returncode}:\n{self.tail()}")
        return b" ready." in self.log.read_bytes()

    def wait_ready(self) -> None:
        """Block until the worker is ready; `RunFailed` after WORKER_READY_S."""
        deadline = time.monotonic() + WORKER_READY_S
        while not self.ready():
            if time.monotonic() > deadline:
                raise RunFailed(f"the worker was not ready after {WORKER_READY_S:.0f} s:\n{self.tail()}")
            time.sleep(0.1)

    def kill(self) -> None:
        """SIGKILL the worker and its pool processes at once: a crash, nothing gets to clean up."""
        with contextlib.suppress(ProcessLookupError):
            os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait(timeout=10)

    def tail(self, lines: int = 15) -> str:
        """The last lines of the worker's log, for a failure message."""
        return f"--- {self.log.name}\n" + "\n".join(self.log.read_text().splitlines()[-lines:])


@dataclass
class Crash:
    """When this script killed attempt 1's worker, started the replacement, and saw it ready (seconds)."""

    killed: Mark
    restarted: Mark | None = None
    ready: Mark | None = None


def environment(settings: Settings) -> dict[str, str]:
    """The children's environment: what `metairl serve` passes on, plus the shortened timings and queue."""
    names = [*TIMINGS, "queue_name"]
    return {
        **child_environment(settings),
        **{f"METAIRL_{n.upper()}": str(getattr(settings, n)) for n in names},
    }


def create_key(env: dict[str, str], lab: str = "reliability") -> str:
    """Run ``metairl keys create`` for `lab` (which also migrates the database) and return the key on its last line."""
    done = subprocess.run(
        [sys.executable, "-m", "metairl_cli.main", "keys", "create", "--lab", lab],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return done.stdout.strip().splitlines()[-1]


def free_port() -> int:
    """A TCP port nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@contextlib.contextmanager
def api_server(env: dict[str, str]) -> Iterator[str]:
    """Run the API under uvicorn as `metairl serve` does; yields its URL once ``/healthz`` answers."""
    port = free_port()
    argv = [sys.executable, "-m", "uvicorn", "--factory", "service.api.app:create_app"]
    api = spawn([*argv, "--host", "127.0.0.1", "--port", str(port), "--log-level", "warning"], env)
    try:
        url = f"http://127.0.0.1:{port}"
        if not wait_healthy(url, {"api": api}, threading.Event()):
            raise RunFailed("the API did not start")
        yield url
    finally:
        shut_down([api])


def upload_demonstrator(api: Client) -> tuple[str, list[str]]:
    """A grid MDP and a demonstrator with three tasks (walk right, up, left), three demonstrations each: ids."""
    mdp_id = api.create_mdp(
        {"kind": "grid", "name": "plate", "width": SIZE, "height": SIZE, "moves": 4, "gamma": 0.9}
    )
    demonstrator_id = api.create_demonstrator(name="reliability figure", metadata={})
    lines, last = (0, 3, 6), SIZE - 1
    walks = {  # state = y·SIZE + x; actions 0, 1, 2 are east, north, west
        "walk right": ([[SIZE * y + x for x in range(SIZE)] for y in lines], 0),
        "walk up": ([[SIZE * y + x for y in range(SIZE)] for x in lines], 1),
        "walk left": ([[SIZE * y + x for x in range(last, -1, -1)] for y in lines], 2),
    }
    task_ids = []
    for name, (paths, action) in walks.items():
        task_ids.append(api.create_task(demonstrator_id, name=name, mdp_id=mdp_id, metadata={}))
        api.add_demonstrations(task_ids[-1], [Trajectory.of(path, [action] * last) for path in paths])
    return demonstrator_id, task_ids


def get_json(api: Client, path: str, **params: str) -> Any:
    """``GET path`` and its JSON body; `MetairlError` for an error answer."""
    response = api.http.get(path, params=params)
    if response.is_error:
        raise MetairlError.from_response(response)
    return response.json()


def poll(api: Client, job_id: str, timeline: Timeline) -> dict[str, Any]:
    """One poll: the job (recorded as a `Poll`) and its whole event log (merged into the timeline)."""
    job = get_json(api, f"/v1/jobs/{job_id}")
    step = job["progress"]["step"] if job["progress"] else None
    timeline.polls.append(Poll(timeline.now(), job["status"], step, job["attempts"]))
    params = {"limit": "100"}
    while True:
        page = get_json(api, f"/v1/jobs/{job_id}/events", **params)
        timeline.events |= {e["id"]: e for e in page["data"]}
        if not page["has_more"]:
            return job
        params["cursor"] = page["next_cursor"]


def run_with_a_crash(
    api: Client, workers: list[Worker], job: dict[str, Any], env: dict[str, str], timeout_s: float
) -> tuple[Timeline, Crash, dict[str, Any]]:
    """Poll the job to its end; SIGKILL the worker part-way through attempt 1, then start a replacement.

    The replacement is appended to ``workers`` (so the caller stops it whatever happens).
    """
    timeline = Timeline(submitted_at=datetime.fromisoformat(job["created_at"]))
    crash: Crash | None = None
    while True:
        job = poll(api, job["id"], timeline)
        step = timeline.polls[-1].step or 0
        if crash is None and job["status"] == "running" and step >= KILL_AT * job["config"]["max_steps"]:
            workers[0].kill()
            crash = Crash(killed=timeline.mark(f"worker killed (SIGKILL) at step {step}"))
        elif (
            crash is not None
            and crash.restarted is None
            and timeline.now() - crash.killed.t >= RESTART_AFTER_S
        ):
            workers.append(Worker.start(env, workers[0].log.with_name("worker-2.log")))
            crash.restarted = timeline.mark("new worker started")
        elif crash is not None and crash.restarted and crash.ready is None and workers[-1].ready():
            crash.ready = timeline.mark("new worker ready (its reaper runs at start, then every interval)")
        if job["status"] in TERMINAL_STATUSES and crash is not None:
            return timeline, crash, job
        if job["status"] in TERMINAL_STATUSES or timeline.now() > timeout_s:
            logs = "\n".join(w.tail() for w in workers)
            raise RunFailed(
                f"job {job['id']} did not get through a worker crash to succeeded within {timeout_s:.0f} s "
                f"(status {job['status']}, attempts {job['attempts']}, error {job['error']!r}):\n{logs}"
            )
        time.sleep(POLL_S)


def summary(timeline: Timeline, crash: Crash) -> list[tuple[float, str]]:
    """The run as (t, what happened), oldest first: the server's status changes and this script's actions."""
    rows = [(0.0, "job submitted (POST /v1/jobs): queued")]
    for e in timeline.status_events()[1:]:  # the first is the submission itself
        rows.append((timeline.since(e["at"]), f"{e['status']} (attempt {e['attempt']}): {e['message']}"))
    rows += [(m.t, m.label) for m in (crash.killed, crash.restarted, crash.ready) if m is not None]
    last_running = max(p.t for p in timeline.polls if p.status == "running" and p.attempts == 1)
    rows.append((last_running, "last poll still showing attempt 1 running (its heartbeat not yet stale)"))
    return sorted(rows)


def report(timeline: Timeline, crash: Crash, job: dict[str, Any], rewards: dict[str, Any]) -> None:
    """Print the events with their times and the headline numbers."""
    print(f"{'t (s)':>7}  event")
    for t, what in summary(timeline, crash):
        print(f"{t:7.2f}  {what}")
    requeued = timeline.since(timeline.requeued()["at"])
    print(
        f"\nkilled at {crash.killed.t:.1f} s; re-queued by the reaper at {requeued:.1f} s "
        f"({requeued - crash.killed.t:.1f} s after the kill); succeeded at {timeline.since(job['finished_at']):.1f} s "
        f"after {job['attempts']} attempts; one result set: baseline + {len(rewards['tasks'])} task rewards; "
        f"{len(timeline.polls)} polls"
    )


def status_bands(timeline: Timeline, end: float) -> list[tuple[float, float, str]]:
    """(start, stop, status) spans between consecutive status changes; the last lasts until ``end``."""
    changes = [(timeline.since(e["at"]), e["status"]) for e in timeline.status_events()]
    starts = [0.0, *(t for t, _ in changes[1:])]
    stops = [*starts[1:], end]
    return [(a, b, status) for a, b, (_, status) in zip(starts, stops, changes, strict=True)]


def draw(timeline: Timeline, crash: Crash, job: dict[str, Any], settings: Settings, out: Path) -> None:
    """The figure: status bands, each attempt's reported step, and vertical markers for the crash and recovery."""
    finished, requeued = timeline.since(job["finished_at"]), timeline.since(timeline.requeued()["at"])
    end = finished * 1.04
    fig = Figure(figsize=(10, 4.8), dpi=100, layout="constrained")
    ax = fig.add_subplot()
    shown: set[str] = set()
    for start, stop, status in status_bands(timeline, end):
        label = None if status in shown else f"status {status}"
        ax.axvspan(start, stop, color=STATUS_COLOURS.get(status, "#dddddd"), alpha=0.45, lw=0, label=label)
        shown.add(status)
    ax.axvspan(
        crash.killed.t,
        requeued,
        facecolor="none",
        edgecolor="#c0392b",
        hatch="//",
        lw=0,
        alpha=0.4,
        label="still 'running', no live worker",
    )
    claims = [timeline.since(e["at"]) for e in timeline.status_events() if e["status"] == "running"]
    ax.plot(
        claims,
        [0] * len(claims),
        "^",
        color="black",
        ms=9,
        clip_on=False,
        label="a worker claims the job (new attempt)",
    )
    for attempt in range(1, job["attempts"] + 1):
        times, steps = timeline.progress(attempt)
        colour = ATTEMPT_COLOURS[(attempt - 1) % len(ATTEMPT_COLOURS)]
        ax.plot(times, steps, ".-", color=colour, lw=2, ms=5, label=f"attempt {attempt}: step reached")
    assert crash.restarted is not None  # the job cannot succeed without the replacement worker
    markers = [
        (crash.killed.t, "worker killed (SIGKILL)", "#c0392b", "-"),
        (crash.restarted.t, "new worker started", "#555555", "--"),
        (requeued, "reaper re-queued the job", "#6a3d9a", ":"),
        (finished, "succeeded", "#1e8449", "-."),
    ]
    for t, label, colour, style in markers:
        ax.axvline(t, color=colour, ls=style, lw=1.8, label=f"{label} ({t:.1f} s)")
    ax.set_xlim(0, end)
    ax.set_ylim(0, job["config"]["max_steps"] * 1.05)
    ax.set_xlabel("seconds since the job was submitted")
    ax.set_ylabel("optimisation step of the fit")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=9, frameon=False)
    fig.suptitle(
        f"A worker SIGKILLed mid-job: the reaper re-queues the job, attempt {job['attempts']} runs it to the end, "
        "one result set is stored\n"
        f"SQLite + {broker_url(settings).split('://')[0]} broker; heartbeat every {settings.job_heartbeat_s:g} s, "
        f"stale after {settings.job_stale_after_s:g} s, reaper every {settings.reaper_interval_s:g} s",
        fontsize=11,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)


def run(out: Path, broker: str | None, max_steps: int, timeout_s: float) -> None:
    """Start the stack in a temporary folder, run a job through a worker crash, then print and draw it."""
    with tempfile.TemporaryDirectory(prefix="metairl-reliability-") as tmp:
        settings = Settings(
            data_dir=Path(tmp) / "var",
            database_url=None,
            broker_url=broker,
            queue_name=f"metairl-reliability-{secrets.token_hex(4)}",
            **TIMINGS,  # type: ignore[arg-type]
        )
        env = environment(settings)
        workers: list[Worker] = []
        try:
            key = create_key(env)
            with api_server(env) as url, Client.connect(url=url, api_key=key) as api:
                workers.append(Worker.start(env, Path(tmp) / "worker-1.log"))
                workers[0].wait_ready()
                demonstrator_id, task_ids = upload_demonstrator(api)
                config = {**CONFIG, "max_steps": max_steps}
                submitted = api.submit_job(demonstrator_id, task_ids=task_ids, config=config)
                job = get_json(api, f"/v1/jobs/{submitted.id}")
                timeline, crash, job = run_with_a_crash(api, workers, job, env, timeout_s)
                rewards = get_json(api, f"/v1/jobs/{job['id']}/rewards")
        finally:
            shut_down(w.process for w in workers)
            delete_queue(settings)
    report(timeline, crash, job, rewards)
    draw(timeline, crash, job, settings, out)
    print(f"\nfigure: {out}")


def main() -> int:
    """Parse the command line and run; exit code 1 with the reason if the job did not get to succeeded."""
    parser = argparse.ArgumentParser(description="Draw what happens to a job when its worker is SIGKILLed.")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "reliability.png", help="PNG to write")
    parser.add_argument(
        "--broker", default=None, help="Celery broker URL (default: the embedded filesystem://)"
    )
    parser.add_argument(
        "--max-steps", type=int, default=1500, help="the job's steps (about 10-20 s of fitting)"
    )
    parser.add_argument("--timeout", type=float, default=180.0, help="seconds the job gets to succeed")
    args = parser.parse_args()
    return exit_code("reliability", lambda: run(args.out, args.broker, args.max_steps, args.timeout))


def exit_code(program: str, action: Callable[[], None]) -> int:
    """Run `action`: 0, or 1 after printing why on stderr (a command that failed, with its output; a run that did
    not get to its end; an error answer of the service)."""
    try:
        action()
    except subprocess.CalledProcessError as exc:
        print(f"{program}: {exc}\n{exc.stdout}{exc.stderr}", file=sys.stderr)
        return 1
    except (RunFailed, MetairlError) as exc:
        print(f"{program}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
