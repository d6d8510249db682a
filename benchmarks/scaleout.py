"""Scale-out: N ``metairl worker`` processes on one Redis broker run N jobs at once.

For each worker count of ``--workers`` it starts the production shape on a fresh PostgreSQL database
(``metairl_scaleout_<random>``) and a ``redis-server`` of its own (free port, no persistence, so the
machine's Redis is never touched): ``metairl keys create``, the API under uvicorn, and N real workers, each
``metairl worker --concurrency 1`` in its own process group. Over HTTP, as a lab does (`metairl_client`), it
uploads one terrain world of ``metairl demo`` (``--size``² states, ``--tasks`` goal tasks with their
demonstrations), submits ``--jobs`` identical jobs on it (fixed seed, ``tolerance`` and ``patience`` 0, so every
job runs exactly ``--steps`` steps) and polls them every ``POLL_S`` until all succeeded. It prints a markdown
table, one row per worker count: wall time from the first submission to the last job's ``finished_at``, the
mean job time (``finished_at − started_at``), the most jobs that ran at the same time (from those intervals),
the peak RSS of each worker (VmHWM summed over the worker's processes: its main process and its pool
process, which runs the fit; pages they share count twice) and the 1-minute load average before → after;
then each job's interval and each worker's CPU seconds (its processes' user + system time since it started).
A pool process imports torch with its first job, so that job's time includes a few seconds of import.
Usage::

    python -m benchmarks.scaleout [--workers 1 2] [--jobs 2] [--steps 2000] [--size 16] [--tasks 4]
        [--threads 0]

Needs PostgreSQL at ``--postgres`` (trust auth) and ``redis-server`` on PATH. Each worker count takes its
jobs' time plus ~15 s of start-up; everything it starts is stopped, and the database and the data folder
removed, at the end of each row, also after an error or ``--timeout``. Nothing is written into the repository.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import re
import secrets
import shutil
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

import redis

from benchmarks.load import children, database, free_port
from benchmarks.reliability import RunFailed, Worker, api_server, create_key, exit_code
from metairl_cli.demo import upload_world
from metairl_cli.demo_experiment import DemoSettings, make_experiment
from metairl_cli.serve import shut_down
from metairl_client import Client, JobState

ROOT = Path(__file__).resolve().parents[1]

POLL_S = 0.5
"""Seconds between two polls of the jobs (and samples of the workers' memory)."""

SHARING = "huber"
"""The jobs' sharing loss (the default config's)."""

PACKAGES = ("torch", "celery", "kombu", "redis", "sqlalchemy", "psycopg", "fastapi", "uvicorn")


@dataclass(frozen=True)
class Interval:
    """When one job ran: seconds since the first submission at which it started and finished."""

    start: float
    stop: float


def max_overlap(intervals: Sequence[Interval]) -> int:
    """The most intervals that contain one moment (one ending as another starts does not overlap it)."""
    edges = sorted([(i.start, 1) for i in intervals] + [(i.stop, -1) for i in intervals])
    running = most = 0
    for _, change in edges:  # at equal times the end (-1) sorts first
        running += change
        most = max(most, running)
    return most


@dataclass(frozen=True)
class Row:
    """One worker count's measurement, as a line of the table."""

    workers: int
    jobs: int
    wall_s: float
    intervals: list[Interval]
    peak_mb: list[float]
    cpu_s: list[float]
    load_before: float
    load_after: float

    def cells(self) -> str:
        """The markdown table line."""
        mean = statistics.mean(i.stop - i.start for i in self.intervals)
        peaks = ", ".join(f"{mb:.0f}" for mb in self.peak_mb)
        return (
            f"| {self.workers} | {self.jobs} | {self.wall_s:.1f} | {mean:.1f} | {max_overlap(self.intervals)} "
            f"| {peaks} | {self.load_before:.2f} → {self.load_after:.2f} |"
        )


HEADER = [
    "| workers | jobs | wall s | mean job s | overlap (max concurrent running) "
    "| peak RSS per worker MB | load avg (1 min) |",
    "| --- | --- | --- | --- | --- | --- | --- |",
]


def table(rows: Sequence[Row]) -> str:
    """The markdown table of the rows."""
    return "\n".join([*HEADER, *(row.cells() for row in rows)])


def peak_rss_mb(pid: int) -> float:
    """VmHWM (peak resident memory) of process `pid` and its children, summed, in MB; 0 for a process gone."""
    total = 0
    for process in (pid, *children(pid)):
        with contextlib.suppress(OSError):
            match = re.search(r"^VmHWM:\s+(\d+) kB", Path(f"/proc/{process}/status").read_text(), re.M)
            total += int(match.group(1)) if match else 0
    return total / 1024


def cpu_seconds(pid: int) -> float:
    """CPU time (user + system) of process `pid` and its children so far, summed; 0 for a process gone."""
    ticks = 0
    for process in (pid, *children(pid)):
        with contextlib.suppress(OSError):
            fields = Path(f"/proc/{process}/stat").read_text().rsplit(")", 1)[1].split()
            ticks += int(fields[11]) + int(fields[12])  # utime, stime: fields 14 and 15 of proc(5)
    return ticks / os.sysconf("SC_CLK_TCK")


@contextlib.contextmanager
def redis_server(folder: Path) -> Iterator[str]:
    """A ``redis-server`` of this run's own on a free loopback port, keeping nothing on disk: its URL."""
    port = free_port()
    argv = ["redis-server", "--port", str(port), "--bind", "127.0.0.1", "--save", "", "--appendonly", "no"]
    server = subprocess.Popen(argv, cwd=folder, stdout=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while True:
            with contextlib.suppress(redis.ConnectionError):
                if redis.Redis(port=port).ping():
                    break
            if time.monotonic() > deadline:
                raise RunFailed("the benchmark's redis-server did not answer within 10 s")
            time.sleep(0.05)
        yield f"redis://127.0.0.1:{port}/0"
    finally:
        server.terminate()
        server.wait(timeout=10)


def experiment(args: argparse.Namespace) -> DemoSettings:
    """The one terrain world (and its goal tasks) that every job fits."""
    return DemoSettings(
        n_worlds=1,
        size=args.size,
        n_hills=6,
        n_demos=args.demos,
        task_counts=(args.tasks,),
        losses=(SHARING,),
        max_steps=args.steps,
    )


def measure(n_workers: int, args: argparse.Namespace) -> Row:
    """Start the stack with `n_workers` workers, run ``args.jobs`` identical jobs to success, stop it all."""
    settings = experiment(args)
    with (
        database("postgres", args.postgres, label="scaleout") as (url, data_dir),
        redis_server(data_dir) as broker,
    ):
        env = {
            **{k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")},
            "METAIRL_DATABASE_URL": url,
            "METAIRL_DATA_DIR": str(data_dir),
            "METAIRL_BROKER_URL": broker,
            "METAIRL_QUEUE_NAME": f"metairl-scaleout-{secrets.token_hex(4)}",
            "METAIRL_WORKER_CONCURRENCY": "1",
            "METAIRL_WORKER_THREADS": str(args.threads),
        }
        key = create_key(env, lab="scaleout")
        workers: list[Worker] = []
        try:
            with api_server(env) as api_url, Client.connect(url=api_url, api_key=key) as api:
                workers += [Worker.start(env, data_dir / f"worker-{i + 1}.log") for i in range(n_workers)]
                for worker in workers:
                    worker.wait_ready()
                world = upload_world(api, make_experiment(settings)[0])
                config = {**settings.job_config(SHARING), "tolerance": 0, "patience": 0}
                load_before = os.getloadavg()[0]
                submitted = datetime.now(UTC)
                jobs = [
                    api.submit_job(world.demonstrator_id, task_ids=world.task_ids, config=config)
                    for _ in range(args.jobs)
                ]
                finished = follow(api, [job.id for job in jobs], workers, args.timeout)
                if any(job.step != args.steps for job in finished):
                    raise RunFailed(f"a job stopped before step {args.steps}: {finished}")
                peaks = [peak_rss_mb(worker.process.pid) for worker in workers]
                cpu = [cpu_seconds(worker.process.pid) for worker in workers]
                load_after = os.getloadavg()[0]
        finally:
            shut_down(worker.process for worker in workers)

    def since(at: datetime | None) -> float:
        """Seconds from the first submission to `at`."""
        assert at is not None  # a succeeded job has both times
        return (at - submitted).total_seconds()

    intervals = [Interval(since(job.started_at), since(job.finished_at)) for job in finished]
    wall = max(i.stop for i in intervals)
    return Row(n_workers, args.jobs, wall, intervals, peaks, cpu, load_before, load_after)


def follow(api: Client, job_ids: list[str], workers: list[Worker], timeout_s: float) -> list[JobState]:
    """Poll the jobs until all succeeded; `RunFailed` (with the workers' logs) if one did not, or after the timeout."""
    deadline = time.monotonic() + timeout_s
    states = {job_id: api.get_job(job_id) for job_id in job_ids}
    while not all(state.finished for state in states.values()):
        if time.monotonic() > deadline:
            logs = "\n".join(worker.tail() for worker in workers)
            raise RunFailed(f"not all jobs finished within {timeout_s:.0f} s:\n{logs}")
        time.sleep(POLL_S)
        states = {
            job_id: state if state.finished else api.get_job(job_id) for job_id, state in states.items()
        }
    failed = [state for state in states.values() if state.status != "succeeded"]
    if failed:
        raise RunFailed(f"job {failed[0].id} ended {failed[0].status}: {failed[0].error}")
    return list(states.values())


def versions() -> str:
    """Python, the packages a worker runs on, redis-server and the commit."""
    parts = [f"Python {platform.python_version()}"]
    for name in PACKAGES:
        with contextlib.suppress(metadata.PackageNotFoundError):
            parts.append(f"{name} {metadata.version(name)}")
    server = subprocess.run(["redis-server", "--version"], capture_output=True, text=True).stdout
    parts.append(" ".join(server.split()[:3]))
    commit = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    )
    if commit.returncode == 0:
        parts.append(f"commit {commit.stdout.strip()}")
    return ", ".join(parts)


def main() -> int:
    """Measure each worker count in turn and print the table; exit code 1 with the reason if a run failed."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts (default 1 2)")
    parser.add_argument("--jobs", type=int, default=2, help="identical jobs per worker count (default 2)")
    parser.add_argument("--steps", type=int, default=2000, help="steps every job runs (default 2000)")
    parser.add_argument("--size", type=int, default=16, help="side of the terrain grid (default 16)")
    parser.add_argument("--tasks", type=int, default=4, help="goal tasks per job (default 4)")
    parser.add_argument("--demos", type=int, default=10, help="demonstrations per task (default 10)")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds the jobs of one row get")
    parser.add_argument(
        "--threads", type=int, default=0, help="METAIRL_WORKER_THREADS of each worker (0: automatic)"
    )
    parser.add_argument("--postgres", default="postgresql://postgres@127.0.0.1:5432/postgres")
    args = parser.parse_args()
    if shutil.which("redis-server") is None:
        sys.exit("scaleout.py needs redis-server on PATH (Debian: apt-get install redis-server)")
    from worker.runner import torch_threads  # the rule the workers apply (imports torch)

    threads = torch_threads(1, size=args.size**2 * args.tasks, threads=args.threads)
    print(
        f"{versions()}; {len(os.sched_getaffinity(0))} cores; jobs: {args.size}×{args.size} terrain, "
        f"{args.tasks} tasks × {args.demos} demonstrations, {SHARING} sharing, {args.steps} steps each; "
        f"one job slot per worker, {threads} torch thread(s) per job",
        flush=True,
    )
    return exit_code("scaleout", lambda: report(args))


def report(args: argparse.Namespace) -> None:
    """Measure each worker count in turn (printing its row when done), then the table and the jobs' intervals."""
    rows = []
    for n_workers in args.workers:
        rows.append(measure(n_workers, args))
        print(rows[-1].cells(), flush=True)
    print(f"\n{table(rows)}")
    for row in rows:
        spans = ", ".join(f"{i.start:.1f}–{i.stop:.1f}" for i in row.intervals)
        cpu = ", ".join(f"{seconds:.1f}" for seconds in row.cpu_s)
        print(
            f"\n{row.workers} worker(s): jobs ran at {spans} s after the first submission; "
            f"CPU s per worker (from its start): {cpu}"
        )


if __name__ == "__main__":
    raise SystemExit(main())
