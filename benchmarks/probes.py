"""The reliability probes as measurements against a real API process (uvicorn, loopback only).

``memory``: for each upload the probe found swelling an API process, a fresh API process on SQLite gets the
request; the table gives its answer, the process's resident size before, its peak (``VmHWM``) and its size
afterwards. ``streams``: ``GET /v1/mdps`` latency on PostgreSQL with N event streams open (several keys: a key
holds at most ``METAIRL_EVENTS_MAX_STREAMS_PER_KEY``). Run from the repository root:

    .venv/bin/python -m benchmarks.probes memory
    .venv/bin/python -m benchmarks.probes streams --streams 200
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import io
import json
import os
import secrets
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

import httpx
import numpy as np

from metairl_cli.keys import create_key
from service.api.app import create_app
from service.settings import Settings
from tests.conftest import fresh_database
from tests.served import free_port

REPO = Path(__file__).resolve().parents[1]

CORRIDOR = {
    "kind": "explicit",
    "name": "corridor",
    "gamma": 0.9,
    "transitions": {"kind": "deterministic", "next_state": [[0, 1], [0, 2], [1, 2]]},
}
"""3 states; action 0 steps left, action 1 right: every probe trajectory is valid on it."""


def status_kb(pid: int, field: str) -> int:
    """A ``/proc/<pid>/status`` field in KiB (VmRSS, VmHWM)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    raise KeyError(field)


@contextlib.contextmanager
def api(folder: Path, database_url: str, extra: dict[str, str] | None = None) -> Iterator[tuple[str, int]]:
    """One uvicorn API process on a free loopback port: (base URL, pid)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("METAIRL_")}
    env |= {"METAIRL_DATA_DIR": str(folder), "METAIRL_DATABASE_URL": database_url} | (extra or {})
    port = free_port()
    log = (folder / f"api-{port}.log").open("wb")
    proc = subprocess.Popen(
        [sys.executable, "-m", "uvicorn", "--factory", "service.api.app:create_app", "--port", str(port)],
        cwd=REPO,
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            assert proc.poll() is None, "the API exited"
            with contextlib.suppress(httpx.TransportError):
                if httpx.get(f"{url}/healthz").status_code == 200:
                    break
            assert time.monotonic() < deadline, "the API did not start"
            time.sleep(0.2)
        yield url, proc.pid
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        log.close()


def keys(database_url: str, folder: Path, n: int) -> list[str]:
    """`n` API keys of new labs (the database migrated on the way)."""
    app = create_app(Settings(data_dir=folder, database_url=database_url))
    with app.state.sessionmaker() as session:
        made = [create_key(session, f"probe-{secrets.token_hex(3)}") for _ in range(n)]
    app.state.engine.dispose()
    return made


def demonstrations_csv(megabytes: float) -> bytes:
    """A demonstrations CSV of about `megabytes` (trajectories of 100 steps on a 3-state corridor)."""
    line = "t{0},{1},0,0\n"
    rows = []
    size, k = 0, 0
    while size < megabytes * 1e6:
        row = line.format(k // 100, k % 100)
        rows.append(row)
        size += len(row)
        k += 1
    return ("trajectory,step,state,action\n" + "".join(rows)).encode()


def explicit_npz() -> bytes:
    """A compressed `.npz` of a 4,000,000 × 8 deterministic MDP (all zeros: about 600 KB)."""
    buffer = io.BytesIO()
    np.savez_compressed(buffer, next_state=np.zeros((4_000_000, 8), dtype=np.int64))
    return buffer.getvalue()


def void_npz() -> bytes:
    """An `.npz` whose member declares 1,000 elements of a 1 MiB void dtype."""
    header = repr({"descr": "|V1048576", "fortran_order": False, "shape": (1000,)}).encode()
    header += b" " * (63 - (len(header) + 10) % 64) + b"\n"
    npy = b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + b"\x00" * 1000
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("features.npy", npy)
    return buffer.getvalue()


def trajectories_json(megabytes: float) -> bytes:
    """A demonstrations JSON body of about `megabytes`."""
    one = {"states": [0, 1, 2, 1] * 75, "actions": [1, 1, 0, 0] * 75}
    n = int(megabytes * 1e6 / len(json.dumps(one)))
    return json.dumps({"trajectories": [one] * n}).encode()


def post_csv(data: bytes, http: httpx.Client, task: str) -> httpx.Response:
    """Upload ``data`` as task ``task``'s demonstrations CSV."""
    return http.post(f"/v1/tasks/{task}/demonstrations", files={"file": ("d.csv", data)})


def post_json(body: bytes, http: httpx.Client, task: str) -> httpx.Response:
    """Upload ``body`` as task ``task``'s demonstrations JSON."""
    return http.post(
        f"/v1/tasks/{task}/demonstrations", content=body, headers={"Content-Type": "application/json"}
    )


def memory(folder: Path) -> None:
    """Peak resident size of a fresh API process per probe (SQLite)."""
    cases: list[tuple[str, Callable[[httpx.Client, str], httpx.Response]]] = []

    def task(http: httpx.Client) -> str:
        dem = http.post("/v1/demonstrators", json={"name": "p"}).json()["id"]
        mdp = http.post("/v1/mdps", json=CORRIDOR).json()["id"]
        return str(
            http.post(f"/v1/demonstrators/{dem}/tasks", json={"name": "t", "mdp_id": mdp}).json()["id"]
        )

    for mb in (51, 201, 20):
        data = demonstrations_csv(mb)
        cases.append(
            (
                f"demonstrations CSV {len(data) / 1e6:.0f} MB",
                partial(post_csv, data),
            )
        )
    for mb in (48, 25, 15):
        body = trajectories_json(mb)
        cases.append(
            (
                f"demonstrations JSON {len(body) / 1e6:.0f} MB",
                partial(post_json, body),
            )
        )
    grid = {"kind": "grid", "name": "g", "width": 2828, "height": 2828, "gamma": 0.9}
    cases.append(
        (
            "grid 2828×2828, 4 moves (32M state-actions), 70-byte body",
            lambda http, t: http.post("/v1/mdps", json=grid),
        )
    )
    npz = explicit_npz()
    cases.append(
        (
            f".npz {len(npz) / 1e3:.0f} KB declaring 4M × 8 int64",
            lambda http, t: http.post(
                "/v1/mdps", files={"file": ("m.npz", npz)}, data={"name": "m", "gamma": "0.9"}
            ),
        )
    )
    bomb = void_npz()
    cases.append(
        (
            f".npz {len(bomb) / 1e3:.0f} KB declaring 1,000 × 1 MiB void",
            lambda http, t: http.post(
                "/v1/mdps", files={"file": ("m.npz", bomb)}, data={"name": "m", "gamma": "0.9"}
            ),
        )
    )
    print("| request | answer | RSS before (MB) | peak RSS (MB) | RSS after (MB) |")
    print("| --- | --- | --- | --- | --- |")
    for name, send in cases:
        with tempfile.TemporaryDirectory(dir=folder) as tmp:
            url_db = f"sqlite:///{tmp}/probe.db"
            key = keys(url_db, Path(tmp), 1)[0]
            with (
                api(Path(tmp), url_db) as (url, pid),
                httpx.Client(base_url=url, headers={"Authorization": f"Bearer {key}"}, timeout=600) as http,
            ):
                t = task(http)
                before = status_kb(pid, "VmRSS") / 1024
                response = send(http, t)
                time.sleep(1.0)
                peak, after = status_kb(pid, "VmHWM") / 1024, status_kb(pid, "VmRSS") / 1024
                answer = f"{response.status_code}"
                if response.status_code >= 400:
                    answer += f" ({response.json()['errors'][0]['message'][:60]}…)"
                print(f"| {name} | {answer} | {before:.0f} | {peak:.0f} | {after:.0f} |", flush=True)


async def streams(folder: Path, n: int) -> None:
    """`GET /v1/mdps` latency (50 requests) with `n` event streams open on a running job (PostgreSQL)."""
    with fresh_database("postgres", folder) as url_db:
        per_key = 50
        made = keys(url_db, folder, max(1, -(-n // per_key)) + 1)
        with api(folder, url_db, {"METAIRL_EVENTS_POLL_S": "0.5"}) as (url, _pid):
            async with httpx.AsyncClient(
                base_url=url, timeout=60, limits=httpx.Limits(max_connections=n + 10)
            ) as http:
                jobs = []
                for key in made[:-1]:
                    auth = {"Authorization": f"Bearer {key}"}
                    dem = (await http.post("/v1/demonstrators", json={"name": "p"}, headers=auth)).json()[
                        "id"
                    ]
                    mdp = (await http.post("/v1/mdps", json=CORRIDOR, headers=auth)).json()["id"]
                    task = (
                        await http.post(
                            f"/v1/demonstrators/{dem}/tasks", json={"name": "t", "mdp_id": mdp}, headers=auth
                        )
                    ).json()["id"]
                    traj = {"trajectories": [{"states": [0, 1, 2], "actions": [1, 1]}]}
                    await http.post(f"/v1/tasks/{task}/demonstrations", json=traj, headers=auth)
                    job = (await http.post("/v1/jobs", json={"demonstrator_id": dem}, headers=auth)).json()[
                        "id"
                    ]
                    jobs.append((auth, job))
                opened: list[int] = []
                stop = asyncio.Event()

                async def hold(auth: dict[str, str], job: str) -> None:
                    async with http.stream(
                        "GET", f"/v1/jobs/{job}/events", headers=auth | {"Accept": "text/event-stream"}
                    ) as response:
                        opened.append(response.status_code)
                        await stop.wait()

                holders = [asyncio.create_task(hold(*jobs[k // per_key])) for k in range(n)]
                while len(opened) < n:
                    await asyncio.sleep(0.1)
                await asyncio.sleep(2.0)
                probe = {"Authorization": f"Bearer {made[-1]}"}
                times, codes = [], []
                for _ in range(50):
                    started = time.perf_counter()
                    codes.append((await http.get("/v1/mdps", headers=probe)).status_code)
                    times.append(time.perf_counter() - started)
                    await asyncio.sleep(0.05)
                stop.set()
                await asyncio.gather(*holders, return_exceptions=True)
    ok = sum(c == 200 for c in opened)
    times.sort()
    print(
        f"{n} streams ({ok} answered 200); GET /v1/mdps × 50: codes {sorted(set(codes))}, median "
        f"{statistics.median(times) * 1000:.0f} ms, p95 {times[int(0.95 * len(times)) - 1] * 1000:.0f} ms, "
        f"max {times[-1] * 1000:.0f} ms"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("probe", choices=["memory", "streams"])
    parser.add_argument("--streams", type=int, default=200)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        if args.probe == "memory":
            memory(Path(folder))
        else:
            asyncio.run(streams(Path(folder), args.streams))


if __name__ == "__main__":
    main()
