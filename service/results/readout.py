"""The motion readout (docs/api.md, "Motion readout"; docs/motion.md, "Readout"): per instructed direction, the kinematic
descriptors of a demonstrator's recordings with 95 % bootstrap intervals, two demonstrators' (or sessions')
differences, and beside them the learned-reward readout of each side's latest succeeded job.

numpy only: the kinematics are `metairl_engine.motion.kinematics`, the learned-reward part `metairl_engine.
motion.readout`; the comparison figure is drawn by `kinematics.comparison_png` (matplotlib, Agg). Nothing
here writes to the database.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_engine.grids import DIRECTION_NAMES
from metairl_engine.motion.kinematics import Movement, compare, comparison_png, movements, summarise
from metairl_engine.motion.readout import (
    BASELINE_CAVEAT,
    Agreement,
    agreement,
    direction_readout,
    path_bend,
    path_offsets,
)
from service.domain.motion import descriptor_units
from service.problems import Conflict
from service.results.engine_modules import metrics
from service.results.units import common_unit
from service.store.blobs import get_array
from service.store.loaders import load_trajectories
from service.store.models.demonstrators import Demonstrator, Task
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, Reward
from service.store.models.mdps import Mdp
from service.store.models.recordings import Recording as RecordingRow
from service.store.recordings import demonstrator_recordings, load_recording


def movement_recordings(session: Session, demonstrator: Demonstrator) -> list[RecordingRow]:
    """The demonstrator's `movements` recordings; 409 with a reason when it has none."""
    rows = demonstrator_recordings(session, demonstrator)
    if not rows:
        raise Conflict(
            f"Demonstrator {demonstrator.id} has no recordings of instructed movements (standing trials have "
            f"none), so there is no motion to read out; upload one with POST "
            f"/v1/demonstrators/{demonstrator.id}/recordings."
        )
    return rows


def recorded_movements(
    session: Session, rows: Sequence[RecordingRow], factors: dict[str, float]
) -> list[Movement]:
    """The out-and-back movements of the recordings ``rows`` (each cut with the segment settings of its
    upload), lengths times each recording's factor to one unit (`common_unit`)."""
    moves = []
    for row in rows:
        rec, segment_settings = load_recording(session, row)
        moves += [in_unit(m, factors[row.id]) for m in movements(rec, segment_settings=segment_settings)]
    return moves


def in_unit(move: Movement, factor: float) -> Movement:
    """A movement's lengths (and speed) times ``factor``: in another length unit; times stay."""
    if factor == 1.0:
        return move
    return replace(
        move,
        peak_reach=move.peak_reach * factor,
        path_length=move.path_length * factor,
        deviation=move.deviation * factor,
        mean_speed=move.mean_speed * factor,
    )


def motion_summary(session: Session, demonstrator: Demonstrator) -> dict[str, Any]:
    """The summary: per direction n_segments and each descriptor's mean with a 95 % interval, lengths in one
    unit; and the learned-reward readout of the demonstrator's latest succeeded job (None where it has none)."""
    rows = movement_recordings(session, demonstrator)
    unit, factors = common_unit(rows)
    moves = recorded_movements(session, rows, factors)
    return {
        "demonstrator_id": demonstrator.id,
        "units": descriptor_units(unit),
        "unit": unit,
        "n_recordings": len(rows),
        **summarise(moves),
        "learned": learned_readout(session, demonstrator, moves, rows),
    }


def motion_comparison(session: Session, a: Demonstrator, b: Demonstrator) -> dict[str, Any]:
    """b minus a per direction and descriptor (with intervals), both sides' summaries in one length unit, and
    the learned-reward readout of each side's latest succeeded job (None where it has none)."""
    rows_a, rows_b = movement_recordings(session, a), movement_recordings(session, b)
    unit, factors = common_unit([*rows_a, *rows_b])
    moves_a, moves_b = (
        recorded_movements(session, rows_a, factors),
        recorded_movements(session, rows_b, factors),
    )
    result = compare(moves_a, moves_b)
    return {
        "a": {"demonstrator_id": a.id, "name": a.name, **result["a"]},
        "b": {"demonstrator_id": b.id, "name": b.name, **result["b"]},
        "units": descriptor_units(unit),
        "unit": unit,
        "directions": result["directions"],
        "learned": {
            "a": learned_readout(session, a, moves_a, rows_a),
            "b": learned_readout(session, b, moves_b, rows_b),
        },
        "links": {"png": "/v1/motion-comparisons?format=png"},
    }


def comparison_figure(comparison: dict[str, Any]) -> bytes:
    """The comparison as one PNG: peak reach per direction of both sides, then b − a per descriptor, each
    axis in the units the JSON states (`descriptor_units`: lengths in ``unit`` or as uploaded, times in the
    recordings' own units of t)."""
    names = (comparison["a"]["name"] or "a", comparison["b"]["name"] or "b")
    if names[0] == names[1]:
        names = (f"{names[0]} (a)", f"{names[1]} (b)")
    return comparison_png(
        comparison, names=names, units=comparison["unit"] or "x, y units", time_unit="t units"
    )


def latest_succeeded_job(session: Session, demonstrator: Demonstrator) -> Job | None:
    """The demonstrator's most recently submitted job that succeeded, if any."""
    query = (
        select(Job)
        .where(
            Job.demonstrator_id == demonstrator.id,
            Job.lab_id == demonstrator.lab_id,
            Job.status == JobStatus.SUCCEEDED.value,
        )
        .order_by(Job.created_at.desc(), Job.id.desc())
        .limit(1)
    )
    return session.execute(query).scalars().first()


def learned_readout(
    session: Session,
    demonstrator: Demonstrator,
    moves: Sequence[Movement],
    recordings: Sequence[RecordingRow],
) -> dict[str, Any] | None:
    """The learned-reward readout of the demonstrator's latest succeeded job, per direction task (tasks named
    by a direction, as recordings name them): ``baseline_ring_centred`` (`direction_readout`: the mean over
    the task's visited states of the baseline minus its mean at the same distance from the centre, the part
    of the baseline out-and-back movements identify; higher = the baseline favours that direction's path),
    ``task_baseline_pearson`` on those states, ``path_bend`` (`readout.path_bend`, model-free: the
    preference's level per direction from which way the paths bend; None unless all eight directions are
    there), and the ``agreement`` of those values with the peak reach of ``moves`` and with the bend of
    each demonstration's path (`readout.agreement`); ``recordings_after_job``: those of ``recordings``
    (the demonstrator's) uploaded after the job. None without a succeeded job."""
    job = latest_succeeded_job(session, demonstrator)
    if job is None:
        return None
    rows = list(
        session.execute(select(Reward).where(Reward.job_id == job.id).order_by(Reward.ordinal)).scalars()
    )
    out: dict[str, Any] = {
        "job_id": job.id,
        "baseline_reward_id": rows[0].id if rows else None,
        "caveat": BASELINE_CAVEAT,
        "recordings_after_job": [r.id for r in recordings if r.created_at > job.created_at],
        "directions": [],
    }
    reach: dict[str, list[float]] = {}
    for m in moves:
        reach.setdefault(m.direction, []).append(m.peak_reach)
    tasks = {t.id: t for t in session.execute(select(Task).where(Task.id.in_(job.task_ids))).scalars()}
    direction_tasks = sorted(
        (
            (r, tasks[r.task_id])
            for r in rows[1:]
            if r.task_id is not None and r.task_id in tasks and tasks[r.task_id].name in DIRECTION_NAMES
        ),
        key=lambda pair: DIRECTION_NAMES.index(pair[1].name),
    )
    first = tasks.get(job.task_ids[0]) if job.task_ids else None
    mdp = session.get(Mdp, first.mdp_id) if first is not None else None
    layout = (mdp.layout if mdp is not None else None) or {}
    if not rows or not direction_tasks or layout.get("channels") != 8:
        out["agreement"] = agreement_body(agreement({}, reach))
        return out
    n_states = rows[0].n_states
    baseline = get_array(session, rows[0].reward_blob_id).astype(np.float64)
    paths = {
        task.name: [t.states for t in load_trajectories(session, task.id)] for _, task in direction_tasks
    }
    states = {d: np.unique(np.concatenate(p)) if p else np.zeros(0, np.int64) for d, p in paths.items()}
    grid = {"width": layout["width"], "height": layout["height"]}
    learned = direction_readout(baseline, states, **grid)
    bend = path_bend(states, **grid)
    for reward, task in direction_tasks:
        values = get_array(session, reward.reward_blob_id).astype(np.float64)
        mask = np.zeros(n_states, dtype=bool)
        mask[states[task.name]] = True
        out["directions"].append(
            {
                "direction": task.name,
                "task_id": task.id,
                "reward_id": reward.id,
                "n_visited_states": len(states[task.name]),
                "baseline_ring_centred": learned.get(task.name),
                "task_baseline_pearson": metrics().pearson(values, baseline, mask=mask),
                "path_bend": bend.get(task.name),
            }
        )
    out["agreement"] = agreement_body(agreement(learned, reach, offsets=path_offsets(paths, **grid)))
    return out


def agreement_body(found: Agreement) -> dict[str, Any]:
    """The API's ``agreement`` object: verdict, detail, and ρ with the permutation p-value in the sign's
    direction, against the peak reach and against the path bend (null where the bend was not checked)."""

    def p_value(rho: float | None, positive: float | None, negative: float | None) -> float | None:
        """The one-sided p-value in the direction of ρ's sign."""
        return None if rho is None else positive if rho >= 0 else negative

    return {
        "verdict": found.verdict,
        "detail": found.detail,
        "spearman": found.spearman,
        "p_value": p_value(found.spearman, found.p_positive, found.p_negative),
        "bend_spearman": found.bend_spearman,
        "bend_p_value": p_value(found.bend_spearman, found.bend_p_positive, found.bend_p_negative),
    }
