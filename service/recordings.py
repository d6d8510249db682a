"""Centre-of-pressure recordings → tasks and demonstrations of a demonstrator (docs/motion.md, API.md §3–4).

A recording (JSON rows or a CSV file with columns ``t,x,y[,instruction]``) is validated and cut by the engine
(`metairl_engine.motion`: samples → cells and directions, skipped cells filled, pauses dropped, segments at
peaks of the distance from the origin, labelled by instruction or direction). Each label becomes, or joins,
the demonstrator's task of that name on the same MDP, and its segments are stored as one demonstration batch.

Everything an upload writes (a velocity grid it creates, tasks, demonstrations, the recording row) goes in
ONE database transaction: the data-layer functions of `service.crud` run on a session joined to an outer
connection transaction in ``rollback_only`` mode, so their own commits only flush and a failure anywhere
rolls the whole upload back. numpy only: the API process never imports torch.
"""

from __future__ import annotations

import json
import re
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
from pydantic import ValidationError
from sqlalchemy import Engine, select, update
from sqlalchemy.orm import Session
from starlette.datastructures import FormData

from metairl_engine import InvalidInput
from metairl_engine.grids import DIRECTION_NAMES
from metairl_engine.motion import NO_INSTRUCTION, DiscretiseSettings, Recording, demonstrations
from service.blobs import put_array
from service.crud import mdps as crud_mdps
from service.crud import tasks as crud_tasks
from service.crud.demonstrations import add_demonstrations
from service.csv_rows import MAX_ERRORS, csv_error, csv_rows
from service.ids import new_id
from service.models.demonstrators import Demonstrator, Task
from service.models.mdps import Mdp
from service.models.recordings import Recording as RecordingRow
from service.pagination import Page, PageParams, paginate
from service.problems import Conflict, Unprocessable, validation_errors
from service.schemas.mdps import GridMdpIn
from service.schemas.recordings import RecordingIn, RecordingOptions, RecordingOut, RecordingTask

Format = Literal["json", "csv"]
REQUIRED_COLUMNS = ("t", "x", "y")
INSTRUCTION_COLUMN = "instruction"
OBJECT_FIELDS = ("bounds", "grid", "discretise", "segment")
"""Form fields of a CSV upload that hold a JSON object (the others are plain strings)."""
SAMPLE_POINTER = re.compile(r"^/samples/(\d+)(/|$)")


@dataclass(frozen=True)
class Samples:
    """Uploaded sample columns; ``lines`` gives the CSV line of every sample (None for JSON)."""

    t: list[float]
    x: list[float]
    y: list[float]
    instruction: list[str | None] | None
    format: Format
    lines: list[int] | None = None

    def located(self, error: InvalidInput) -> Unprocessable:
        """The engine's issues as a 422, each sample's CSV line added to its message."""
        items = []
        for issue in error.issues:
            match = SAMPLE_POINTER.match(issue.pointer)
            line = self.lines[int(match.group(1))] if match and self.lines else None
            suffix = f" (CSV line {line})" if line else ""
            items.append({"pointer": issue.pointer, "message": issue.message + suffix})
        first = items[0]
        return Unprocessable(
            f"The recording is invalid. {first['pointer'] or '/'}: {first['message']}", errors=items
        )


def json_samples(body: RecordingIn) -> Samples:
    """The sample columns of a JSON body (the instruction column only if some sample has one)."""
    rows = body.samples
    given = any(r.instruction is not None for r in rows)
    return Samples(
        t=[r.t for r in rows],
        x=[r.x for r in rows],
        y=[r.y for r in rows],
        instruction=[r.instruction for r in rows] if given else None,
        format="json",
    )


def csv_samples(data: bytes) -> Samples:
    """Parse a CSV with header ``t,x,y`` and optionally ``instruction``; 422 naming sample and line."""
    present, rows = csv_rows(data, required=REQUIRED_COLUMNS, optional=(INSTRUCTION_COLUMN,))
    values: dict[str, list[float]] = {c: [] for c in REQUIRED_COLUMNS}
    instruction: list[str | None] = []
    lines: list[int] = []
    errors: list[tuple[str, str]] = []
    for line, cells in rows:
        k = len(lines)
        for c in REQUIRED_COLUMNS:
            try:
                values[c].append(float(cells[c]))
            except ValueError:
                values[c].append(float("nan"))
                errors.append((f"/samples/{k}/{c}", f"{c} {cells[c]!r} is not a number (CSV line {line})"))
        instruction.append(cells.get(INSTRUCTION_COLUMN) or None)
        lines.append(line)
        if len(errors) >= MAX_ERRORS:
            break
    if errors:
        raise csv_error(errors)
    return Samples(
        t=values["t"],
        x=values["x"],
        y=values["y"],
        instruction=instruction if INSTRUCTION_COLUMN in present else None,
        format="csv",
        lines=lines,
    )


def form_options(form: FormData) -> RecordingOptions:
    """The options of a CSV upload from its form fields (``bounds``, ``grid``, ``discretise``, ``segment``
    as JSON objects; ``mdp_id`` and ``name`` as text); 422 with pointers as for a JSON body."""
    raw: dict[str, Any] = {}
    for key, value in form.items():
        if not isinstance(value, str):
            continue
        if key not in OBJECT_FIELDS:
            raw[key] = value
            continue
        try:
            raw[key] = json.loads(value)
        except ValueError as exc:
            raise Unprocessable(
                f"The form field {key} must be a JSON object.",
                errors=[{"pointer": f"/{key}", "message": f"is not valid JSON ({exc})"}],
            ) from exc
    try:
        return RecordingOptions.model_validate(raw)
    except ValidationError as exc:
        raise validation_errors(exc.errors(include_url=False), raw) from exc


def _invalid(pointer: str, message: str) -> Unprocessable:
    """A 422 with one error."""
    return Unprocessable(
        f"The recording is invalid. {pointer}: {message}", errors=[{"pointer": pointer, "message": message}]
    )


@dataclass(frozen=True)
class Target:
    """The MDP a recording maps onto: an existing row, or (``row`` None) ``grid`` to create in the upload."""

    row: Mdp | None
    grid: GridMdpIn | None
    width: int
    height: int


def _target(session: Session, options: RecordingOptions, *, lab_id: str) -> Target:
    """Resolve ``mdp_id`` (a velocity grid of the lab) or ``grid`` (reuse an identical grid, else create)."""
    if options.mdp_id is not None and options.grid is None:
        row = _velocity_mdp(session, options.mdp_id, lab_id=lab_id)
        assert row.layout is not None
        return Target(row=row, grid=None, width=row.layout["width"], height=row.layout["height"])
    if options.grid is None or options.mdp_id is not None:
        raise _invalid("/mdp_id", 'give either "mdp_id" (a velocity-grid MDP) or "grid" (width, height)')
    g = options.grid
    body = GridMdpIn(
        kind="grid",
        name=f"velocity grid {g.width}×{g.height}",
        width=g.width,
        height=g.height,
        velocity=True,
        gamma=g.gamma,
    )
    return Target(row=_existing_grid(session, body, lab_id=lab_id), grid=body, width=g.width, height=g.height)


def _velocity_mdp(session: Session, mdp_id: str, *, lab_id: str) -> Mdp:
    """The lab's MDP `mdp_id` if it is a velocity grid (a layout with 8 channels covering every state)."""
    row = session.get(Mdp, mdp_id)
    if row is None or row.lab_id != lab_id:
        raise _invalid("/mdp_id", f"no MDP with id {mdp_id!r}")
    layout = row.layout or {}
    if layout.get("channels") != 8 or row.n_states != 8 * layout.get("width", 0) * layout.get("height", 0):
        raise _invalid(
            "/mdp_id",
            f"MDP {mdp_id!r} is not a velocity grid (a layout with 8 velocity channels); create one with "
            'POST /v1/mdps {"kind": "grid", "velocity": true, ...} or send "grid" instead',
        )
    return row


def _existing_grid(session: Session, body: GridMdpIn, *, lab_id: str) -> Mdp | None:
    """The lab's oldest grid MDP built with exactly these parameters, if any."""
    wanted = body.model_dump(exclude={"kind", "name", "gamma"}) | {"moves": 8}
    rows = session.execute(
        select(Mdp)
        .where(Mdp.lab_id == lab_id, Mdp.source == "grid", Mdp.gamma == body.gamma)
        .order_by(Mdp.created_at, Mdp.id)
    ).scalars()
    return next((r for r in rows if r.grid == wanted), None)


def _mdp_id(session: Session, target: Target, *, lab_id: str) -> str:
    """The id of the target MDP, creating the grid first if the lab has none like it."""
    if target.row is not None:
        return target.row.id
    assert target.grid is not None
    mdp, params = crud_mdps.build_grid(target.grid)
    return crud_mdps.create_mdp(
        session, lab_id=lab_id, name=target.grid.name, source="grid", mdp=mdp, grid=params
    ).id


def _task_for(
    session: Session, demonstrator: Demonstrator, *, label: str, mdp_id: str, recording_id: str
) -> tuple[Task, bool]:
    """The demonstrator's task named `label` on `mdp_id` (oldest first), or a new one; and whether it is new.

    A task of that name on another MDP is a 409: tasks fitted together must share one state space.
    """
    same_name = (
        session.execute(
            select(Task)
            .where(
                Task.demonstrator_id == demonstrator.id,
                Task.lab_id == demonstrator.lab_id,
                Task.name == label,
            )
            .order_by(Task.created_at, Task.id)
        )
        .scalars()
        .all()
    )
    joined = next((task for task in same_name if task.mdp_id == mdp_id), None)
    if joined is not None:
        return joined, False
    if same_name:
        raise Conflict(
            f"Task {same_name[0].id!r} ({label!r}) of this demonstrator is on MDP {same_name[0].mdp_id!r}, "
            f"not {mdp_id!r}; upload onto that MDP or use another demonstrator."
        )
    created = crud_tasks.create_task(
        session,
        demonstrator,
        name=label,
        mdp_id=mdp_id,
        metadata={"direction": label, "recording_id": recording_id},
    )
    return session.get_one(Task, created.id), True


def lock_demonstrator(session: Session, demonstrator_id: str) -> None:
    """Hold the demonstrator's row until the transaction ends, so concurrent uploads find or create its tasks
    one at a time (two uploads with a new label join one task). A no-op UPDATE: a row lock on PostgreSQL, the
    write lock taken before any read on SQLite."""
    session.execute(update(Demonstrator).where(Demonstrator.id == demonstrator_id).values(id=Demonstrator.id))


def add_recording(
    session: Session, demonstrator: Demonstrator, options: RecordingOptions, samples: Samples
) -> RecordingOut:
    """Validate and cut the recording, then store grid, tasks, demonstrations and the recording atomically."""
    lab_id = demonstrator.lab_id
    target = _target(session, options, lab_id=lab_id)
    discretise = DiscretiseSettings(
        width=target.width, height=target.height, smooth_s=options.discretise.smooth_s
    )
    try:
        rec = Recording.build(
            t=samples.t, x=samples.x, y=samples.y, bounds=options.bounds, instruction=samples.instruction
        )
        cut = demonstrations(rec, discretise_settings=discretise, segment_settings=options.segment)
    except InvalidInput as exc:
        raise samples.located(exc) from exc
    recording_id = new_id("rec")
    engine = session.get_bind()
    assert isinstance(engine, Engine)
    with (
        engine.connect() as connection,
        connection.begin(),
        Session(bind=connection, join_transaction_mode="rollback_only", expire_on_commit=False) as tx,
    ):
        lock_demonstrator(tx, demonstrator.id)
        mdp_id = _mdp_id(tx, target, lab_id=lab_id)
        tasks = []
        for label, trajectories in cut.by_label.items():
            task, created = _task_for(tx, demonstrator, label=label, mdp_id=mdp_id, recording_id=recording_id)
            batch = add_demonstrations(tx, task, trajectories, fmt=samples.format)
            tasks.append(
                RecordingTask(
                    label=label,
                    task_id=task.id,
                    created=created,
                    demonstration_id=batch.id,
                    n_trajectories=batch.n_trajectories,
                    n_steps=batch.n_steps,
                )
            )
        row = RecordingRow(
            id=recording_id,
            lab_id=lab_id,
            demonstrator_id=demonstrator.id,
            mdp_id=mdp_id,
            name=options.name,
            format=samples.format,
            n_samples=len(rec.t),
            duration=float(rec.t[-1] - rec.t[0]),
            samples_blob_id=put_array(tx, np.stack([rec.t, rec.x, rec.y], axis=1), lab_id=lab_id),
            instructions_blob_id=None
            if rec.instruction is None
            else put_array(tx, _instruction_codes(rec.instruction), lab_id=lab_id),
            settings={
                "bounds": asdict(rec.bounds),
                "discretise": asdict(discretise),
                "segment": asdict(options.segment),
            },
            summary={
                "mdp_created": target.row is None,
                "segments": {t.label: t.n_trajectories for t in tasks},
                "dropped_segments": len(cut.dropped),
                "dropped_samples": len(rec.t) - len(np.unique(cut.path.sample)),
                "tasks": [t.model_dump() for t in tasks],
            },
        )
        tx.add(row)
        tx.commit()
    return render(row)


def _instruction_codes(instruction: np.ndarray) -> np.ndarray:
    """Instructions as indices into `DIRECTION_NAMES` (int32), -1 where there was none."""
    codes = {name: k for k, name in enumerate(DIRECTION_NAMES)} | {NO_INSTRUCTION: -1}
    return np.array([codes[v] for v in instruction.tolist()], dtype=np.int32)


def render(row: RecordingRow) -> RecordingOut:
    """The API representation of a recording row."""
    return RecordingOut.model_validate(
        {
            "id": row.id,
            "created_at": row.created_at,
            "demonstrator_id": row.demonstrator_id,
            "mdp_id": row.mdp_id,
            "name": row.name,
            "format": row.format,
            "n_samples": row.n_samples,
            "duration": row.duration,
            "settings": row.settings,
            **row.summary,
        }
    )


def list_recordings(session: Session, demonstrator: Demonstrator, *, page: PageParams) -> Page[RecordingOut]:
    """One page of a demonstrator's recordings, newest first."""
    query = select(RecordingRow).where(
        RecordingRow.demonstrator_id == demonstrator.id, RecordingRow.lab_id == demonstrator.lab_id
    )
    return paginate(session, query, RecordingRow, page, render)
