"""Centre-of-pressure recordings → tasks and demonstrations of a demonstrator (docs/motion.md; docs/api.md, "Centre-of-pressure recordings").

A recording (JSON rows, a CSV file with columns ``t,x,y[,instruction]``, or a force-plate file read into
such samples by `service.files.force_plates`) is validated and cut by the engine
(`metairl_engine.motion.recording`: samples → cells and directions, skipped cells filled, pauses dropped, segments at
peaks of the distance from the origin, labelled by instruction or direction). Each label becomes, or joins,
the demonstrator's task of that name on the same MDP, and its segments are stored as one demonstration batch.

Everything an upload writes (a velocity grid it creates, tasks, demonstrations, the recording row) goes in
the caller's ONE transaction (nothing here commits), so a failure anywhere rolls the whole upload back. The
samples are parsed by `service.files.recording_samples`. numpy only: the API process never imports torch.
"""

from __future__ import annotations

from collections.abc import Mapping
from collections.abc import Set as AbstractSet
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from sqlalchemy import select, update
from sqlalchemy.orm import Session

from metairl_engine import InvalidInput, Issue
from metairl_engine.demos import Trajectory
from metairl_engine.errors import check
from metairl_engine.grids import DIRECTION_NAMES
from metairl_engine.motion.recording import (
    NO_INSTRUCTION,
    Bounds,
    Demonstrations,
    DiscretiseSettings,
    Recording,
    SegmentSettings,
    demonstrations,
)
from metairl_engine.motion.sway import MIN_SWAY_SAMPLES
from service.domain.mdps import GridMdpIn
from service.domain.recordings import GridIn, RecordingOptions, RecordingTask
from service.files.recording_samples import Samples, float32_issues
from service.problems import Conflict, gathering
from service.settings import Settings
from service.sizes import grid_issues
from service.store import mdps
from service.store.blobs import get_array, put_array
from service.store.demonstrations import add_demonstrations
from service.store.ids import new_id
from service.store.loaders import batch_trajectories
from service.store.models.demonstrators import Demonstration, Demonstrator, Task
from service.store.models.mdps import Mdp
from service.store.models.recordings import Recording as RecordingRow
from service.store.owned import get_owned
from service.store.paging import PageParams, RowPage, paginate
from service.store.tasks import create_task


@dataclass(frozen=True)
class Target:
    """The MDP a recording maps onto: an existing row, or (``row`` None) ``grid`` to create in the upload."""

    row: Mdp | None
    grid: GridMdpIn | None
    width: int
    height: int


def _target(session: Session, mdp_id: str | None, grid: GridIn | None, *, lab_id: str) -> Target:
    """Resolve ``mdp_id`` (a velocity grid of the lab) or ``grid`` (reuse an identical grid, else create)."""
    if mdp_id is not None and grid is None:
        row = _velocity_mdp(session, mdp_id, lab_id=lab_id)
        assert row.layout is not None
        return Target(row=row, grid=None, width=row.layout["width"], height=row.layout["height"])
    if grid is None or mdp_id is not None:
        check([Issue("/mdp_id", 'give either "mdp_id" (a velocity-grid MDP) or "grid" (width, height)')])
    assert grid is not None  # else check raised
    body = GridMdpIn(
        kind="grid",
        name=f"velocity grid {grid.width}×{grid.height}",
        width=grid.width,
        height=grid.height,
        velocity=True,
        gamma=grid.gamma,
    )
    return Target(
        row=_existing_grid(session, body, lab_id=lab_id), grid=body, width=grid.width, height=grid.height
    )


def _velocity_mdp(session: Session, mdp_id: str, *, lab_id: str) -> Mdp:
    """The lab's MDP `mdp_id` if it is a velocity grid (a layout with 8 channels covering every state)."""
    row = session.get(Mdp, mdp_id)
    if row is None or row.lab_id != lab_id:
        check([Issue("/mdp_id", f"no MDP with id {mdp_id!r}")])
    assert row is not None  # else check raised
    layout = row.layout or {}
    if layout.get("channels") != 8 or row.n_states != 8 * layout.get("width", 0) * layout.get("height", 0):
        message = (
            f"MDP {mdp_id!r} is not a velocity grid (a layout with 8 velocity channels); create one with "
            'POST /v1/mdps {"kind": "grid", "velocity": true, ...} or send "grid" instead'
        )
        check([Issue("/mdp_id", message)])
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
    mdp, params = mdps.build_grid(target.grid)
    return mdps.create_mdp(
        session, lab_id=lab_id, name=target.grid.name, source="grid", mdp=mdp, grid=params
    ).id


def _task_for(
    session: Session,
    demonstrator: Demonstrator,
    *,
    label: str,
    mdp_id: str,
    target: Target,
    recording_id: str,
) -> tuple[Task, bool]:
    """The demonstrator's task named `label` on `mdp_id` (oldest first), or a new one; and whether it is new.

    A task of that name on another MDP is a 409 naming the field that chose `mdp_id` (``target``): tasks
    fitted together must share one state space. A grid made for this upload is named by its size, not by an
    id the rollback leaves to nothing.
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
        field, asked = (
            ("/mdp_id", f"MDP {mdp_id!r}")
            if target.grid is None
            else ("/grid", f"a {target.width}×{target.height} velocity grid")
        )
        message = (
            f"Task {same_name[0].id!r} ({label!r}) of this demonstrator is on MDP {same_name[0].mdp_id!r}, "
            f"not on {asked}"
        )
        raise Conflict(
            f"{message}; upload with that `mdp_id` or use another demonstrator.",
            errors=[{"pointer": field, "message": message}],
        )
    created = create_task(
        session,
        demonstrator,
        name=label,
        mdp_id=mdp_id,
        metadata={"direction": label, "recording_id": recording_id},
    )
    return created, True


def lock_demonstrator(session: Session, demonstrator_id: str) -> None:
    """Hold the demonstrator's row until the transaction ends, so concurrent uploads find or create its tasks
    one at a time (two uploads with a new label join one task). A no-op UPDATE: a row lock on PostgreSQL, the
    write lock taken before any read on SQLite."""
    session.execute(update(Demonstrator).where(Demonstrator.id == demonstrator_id).values(id=Demonstrator.id))


def _window_issues(rec: Recording, windows: dict[str, float]) -> list[Issue]:
    """An issue per smoothing window (pointer: seconds) spanning more samples than the recording has: it would
    smooth nothing useful and its padding would take memory in proportion (1e308 overflowed)."""
    if len(rec.t) < 2:
        return []
    issues = []
    for pointer, seconds in windows.items():
        span = seconds * rec.sample_rate
        if not span <= len(rec.t):
            issues.append(
                Issue(
                    pointer,
                    f"spans {span:.3g} samples, more than the recording's {len(rec.t)}; use a shorter window",
                )
            )
    return issues


MOVEMENTS_ONLY = ("mdp_id", "grid", "discretise", "segment")
"""Upload options that only the ``movements`` protocol uses."""


@dataclass(frozen=True)
class Checked:
    """An upload that passed every check, ready to store: its samples as the engine's `Recording` and, for
    ``movements``, the MDP they map onto, how they were discretised and their cut (None for ``standing``)."""

    rec: Recording
    target: Target | None = None
    discretise: DiscretiseSettings | None = None
    cut: Demonstrations | None = None


def check_upload(
    session: Session,
    options: Mapping[str, Any],
    sent: AbstractSet[str],
    samples: Samples | None,
    *,
    lab_id: str,
    settings: Settings,
) -> tuple[Checked | None, list[Issue]]:
    """Every check of an upload before anything is written, and the upload they passed (None if one failed or
    could not run): values past float32, a grid over the size limits, options the protocol does not take, the
    MDP, the samples on the plate, the smoothing windows and the cut. ``options`` holds the options that pass
    the schema (`valid_fields`; every one of a valid body), ``sent`` the names among them the upload gave,
    ``samples`` is None when they fail it: a check runs only when what it reads is there and the checks it
    builds on passed, so a body the schema refuses gets every problem found in its other parts."""
    issues: list[Issue] = []
    fitting = None
    if samples is not None:
        too_big = float32_issues(samples)
        issues += too_big
        fitting = None if too_big else samples
    grid = options.get("grid")
    sized = [] if grid is None else _grid_issues(grid, settings)
    issues += sized
    protocol = options.get("protocol")
    if protocol == "standing":
        issues += [
            Issue(f"/{name}", 'applies to protocol "movements" only; a standing recording is not cut')
            for name in MOVEMENTS_ONLY
            if name in sent
        ]
        if fitting is None or "bounds" not in options:
            return None, issues
        rec = gathering(issues, lambda: _standing(options["bounds"], fitting))
        return (None if rec is None else Checked(rec)), issues
    if protocol != "movements":  # refused by the schema: nothing else to check
        return None, issues
    bounds = options.get("bounds")
    if "bounds" in options and bounds is None:
        issues.append(
            Issue("/bounds", 'is required for protocol "movements": the plate\'s x_min, x_max, y_min, y_max')
        )
    target = None
    if not sized and {"mdp_id", "grid"} <= options.keys():
        target = gathering(issues, lambda: _target(session, options["mdp_id"], grid, lab_id=lab_id))
    if fitting is None or bounds is None:
        return None, issues
    rec = gathering(
        issues,
        lambda: Recording.build(
            t=fitting.t, x=fitting.x, y=fitting.y, bounds=bounds, instruction=fitting.instruction
        ),
    )
    if rec is None or not {"discretise", "segment"} <= options.keys():
        return None, issues
    discretise_in, segment = options["discretise"], options["segment"]
    windows = _window_issues(
        rec, {"/discretise/smooth_s": discretise_in.smooth_s, "/segment/smooth_s": segment.smooth_s}
    )
    issues += windows
    if windows or target is None:
        return None, issues
    discretise = DiscretiseSettings(width=target.width, height=target.height, smooth_s=discretise_in.smooth_s)
    cut = gathering(
        issues, lambda: demonstrations(rec, discretise_settings=discretise, segment_settings=segment)
    )
    return (None if cut is None else Checked(rec, target, discretise, cut)), issues


def _grid_issues(grid: GridIn, settings: Settings) -> list[Issue]:
    """The size limits of `POST /v1/mdps` on the velocity grid an upload may create, at ``/grid``."""
    return grid_issues(
        width=grid.width,
        height=grid.height,
        moves=8,
        stay=False,
        slip=0.0,
        velocity=True,
        settings=settings,
        pointer="/grid",
    )


def add_recording(
    session: Session,
    demonstrator: Demonstrator,
    options: RecordingOptions,
    samples: Samples,
    settings: Settings,
) -> RecordingRow:
    """Check the upload (`check_upload`: every problem in one 422, each sample's CSV line named), then add grid,
    tasks, demonstrations and the recording row; a ``standing`` recording is stored whole (`add_standing`).

    The demonstrator's row is locked first (`lock_demonstrator`) until the caller's transaction ends."""
    checked, issues = check_upload(
        session,
        dict(options),
        options.model_fields_set,
        samples,
        lab_id=demonstrator.lab_id,
        settings=settings,
    )
    if issues:
        raise samples.located(InvalidInput(issues))
    assert checked is not None  # every check ran and passed
    if checked.cut is None:
        return add_standing(session, demonstrator, options, samples, checked.rec)
    assert checked.target is not None and checked.discretise is not None
    rec, target, cut = checked.rec, checked.target, checked.cut
    lab_id = demonstrator.lab_id
    recording_id = new_id("rec")
    lock_demonstrator(session, demonstrator.id)
    mdp_id = _mdp_id(session, target, lab_id=lab_id)
    tasks = []
    for label, trajectories in cut.by_label.items():
        task, created = _task_for(
            session, demonstrator, label=label, mdp_id=mdp_id, target=target, recording_id=recording_id
        )
        batch = add_demonstrations(session, task, trajectories, fmt=samples.format)
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
        protocol="movements",
        meta=options.metadata,
        name=options.name,
        format=samples.format,
        n_samples=len(rec.t),
        duration=float(rec.t[-1] - rec.t[0]),
        samples_blob_id=put_array(session, np.stack([rec.t, rec.x, rec.y], axis=1), lab_id=lab_id),
        instructions_blob_id=None
        if rec.instruction is None
        else put_array(session, _instruction_codes(rec.instruction), lab_id=lab_id),
        settings={
            "bounds": asdict(rec.bounds),
            "discretise": asdict(checked.discretise),
            "segment": asdict(options.segment),
        }
        | _units_and_plate(options, samples),
        summary={
            "mdp_created": target.row is None,
            "segments": {t.label: t.n_trajectories for t in tasks},
            "dropped_segments": len(cut.dropped),
            "dropped_samples": len(rec.t) - len(np.unique(cut.path.sample)),
            "tasks": [t.model_dump() for t in tasks],
        },
    )
    session.add(row)
    session.flush()
    return row


def add_standing(
    session: Session, demonstrator: Demonstrator, options: RecordingOptions, samples: Samples, rec: Recording
) -> RecordingRow:
    """Store a checked quiet-standing recording whole: no MDP, no segments, no tasks."""
    row = RecordingRow(
        id=new_id("rec"),
        lab_id=demonstrator.lab_id,
        demonstrator_id=demonstrator.id,
        mdp_id=None,
        protocol="standing",
        meta=options.metadata,
        name=options.name,
        format=samples.format,
        n_samples=len(rec.t),
        duration=float(rec.t[-1] - rec.t[0]),
        samples_blob_id=put_array(
            session, np.stack([rec.t, rec.x, rec.y], axis=1), lab_id=demonstrator.lab_id
        ),
        instructions_blob_id=None,
        settings={"bounds": asdict(rec.bounds), "bounds_from": "upload" if options.bounds else "samples"}
        | _units_and_plate(options, samples),
        summary={
            "mdp_created": False,
            "segments": {},
            "dropped_segments": 0,
            "dropped_samples": 0,
            "tasks": [],
        },
    )
    session.add(row)
    session.flush()
    return row


def standing_recording(options: RecordingOptions, samples: Samples) -> Recording:
    """The samples of a standing upload as a `Recording` (`_standing`); 422 naming the sample or the reason."""
    try:
        return _standing(options.bounds, samples)
    except InvalidInput as exc:
        raise samples.located(exc) from exc


def _standing(bounds: Bounds | None, samples: Samples) -> Recording:
    """The samples of a standing upload as a `Recording` in `bounds` (else their own extent), with enough
    samples for the sway measures and a COP that moves; `InvalidInput` naming the sample or the reason."""
    rec = Recording.build(
        t=samples.t, x=samples.x, y=samples.y, bounds=bounds or _extent(samples), min_samples=MIN_SWAY_SAMPLES
    )
    if np.ptp(rec.x) == 0 and np.ptp(rec.y) == 0:
        hint = " (the plate's moments are zero: a C3D's FORCE_PLATFORM:ORIGIN may lack the sensor offsets)"
        message = (
            f"the centre of pressure never moves over the {len(rec.t)} samples, so there is no sway to measure"
            + (hint if samples.plate is not None else "")
        )
        check([Issue("/samples", message)])
    return rec


def _extent(samples: Samples) -> Bounds:
    """The samples' own rectangle (a flat axis widened by a hair so it is not empty); NaN left to `build`."""
    out = []
    for values in (samples.x, samples.y):
        finite = np.asarray(values, dtype=np.float64)
        finite = finite[np.isfinite(finite)]
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        pad = 0.0 if hi > lo else max(abs(lo), 1.0) * 1e-9
        out += [lo - pad, hi + pad]
    return Bounds(*out)


def _units_and_plate(options: RecordingOptions, samples: Samples) -> dict[str, Any]:
    """The length unit of the stored COP (metres for a plate file, else the upload's `units`, if given) and
    how a plate file was read."""
    if samples.plate is not None:
        return {"units": "m", "plate": samples.plate}
    return {"units": options.units}


def _instruction_codes(instruction: np.ndarray) -> np.ndarray:
    """Instructions as indices into `DIRECTION_NAMES` (int32), -1 where there was none."""
    codes = {name: k for k, name in enumerate(DIRECTION_NAMES)} | {NO_INSTRUCTION: -1}
    return np.array([codes[v] for v in instruction.tolist()], dtype=np.int32)


def list_recordings(
    session: Session, demonstrator: Demonstrator, *, page: PageParams
) -> RowPage[RecordingRow]:
    """One page of a demonstrator's recordings, newest first."""
    query = select(RecordingRow).where(
        RecordingRow.demonstrator_id == demonstrator.id, RecordingRow.lab_id == demonstrator.lab_id
    )
    return paginate(session, query, page, key=(RecordingRow.created_at, RecordingRow.id))


def get_recording(session: Session, recording_id: str, *, lab_id: str) -> RecordingRow:
    """The lab's recording, or 404."""
    return get_owned(session, RecordingRow, recording_id, lab_id=lab_id, what="recording")


def demonstrator_recordings(
    session: Session, demonstrator: Demonstrator, protocol: str = "movements"
) -> list[RecordingRow]:
    """Every recording of a demonstrator under `protocol`, oldest first."""
    query = (
        select(RecordingRow)
        .where(
            RecordingRow.demonstrator_id == demonstrator.id,
            RecordingRow.lab_id == demonstrator.lab_id,
            RecordingRow.protocol == protocol,
        )
        .order_by(RecordingRow.created_at, RecordingRow.id)
    )
    return list(session.execute(query).scalars())


def load_recording(session: Session, row: RecordingRow) -> tuple[Recording, SegmentSettings]:
    """The stored samples of a recording as the engine's `Recording` (instructions by name), and the segment
    settings it was cut with (so a readout finds the same movements as the upload)."""
    samples = get_array(session, row.samples_blob_id).astype(np.float64)
    instruction = None
    if row.instructions_blob_id is not None:
        codes = get_array(session, row.instructions_blob_id)
        names = np.array([*DIRECTION_NAMES, NO_INSTRUCTION], dtype=object)
        instruction = names[np.where(codes < 0, len(DIRECTION_NAMES), codes)].astype(str)
    rec = Recording(
        t=samples[:, 0],
        x=samples[:, 1],
        y=samples[:, 2],
        bounds=Bounds(**row.settings["bounds"]),
        instruction=instruction,
    )
    raw = dict(row.settings.get("segment", {}))
    if raw.get("origin") is not None:
        raw["origin"] = tuple(raw["origin"])
    if "directions" in raw:
        raw["directions"] = tuple(raw["directions"])
    return rec, SegmentSettings(**raw)


@dataclass(frozen=True)
class CutSegment:
    """One demonstration a recording was cut into: its label (task name), task, batch and trajectory."""

    label: str
    task_id: str
    demonstration_id: str
    index: int
    """Position within the label's segments of this recording (time order)."""
    trajectory: Trajectory


def recording_demonstrations(session: Session, row: RecordingRow) -> list[CutSegment]:
    """The demonstrations the upload of `row` stored, label by label in upload order; batches deleted since
    (alone, their ``demonstration_id`` then null, or with their task) are left out."""
    out = []
    for entry in row.summary.get("tasks", []):
        batch = session.get(Demonstration, entry["demonstration_id"]) if entry["demonstration_id"] else None
        if batch is None or batch.lab_id != row.lab_id:
            continue
        out += [
            CutSegment(
                label=entry["label"],
                task_id=entry["task_id"],
                demonstration_id=batch.id,
                index=k,
                trajectory=trajectory,
            )
            for k, trajectory in enumerate(batch_trajectories(session, batch))
        ]
    return out
