"""Files of a reward, value function or policy (json, npy, csv, png), of a task's true reward (npy, csv), of the
comparison matrix, with their ETags, and of a demonstration batch (csv); the npy and json downloads also straight
from the stored bytes (`keyed_stored_file`, read on the event loop)."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from sqlalchemy import ColumnElement, Row, and_, bindparam, select
from sqlalchemy.orm import Session

from metairl_engine.mdp import Layout

if TYPE_CHECKING:
    pass

from service.domain.rewards import (
    ComparisonMatrix,
    Format,
    Overlay,
    Quantity,
)
from service.files import csv_demonstrations, exports, images
from service.problems import Conflict, Unprocessable
from service.results.rewards import RewardContext, blob_id_of, not_stored
from service.store.blobs import blob_sha256, get_array
from service.store.keys import KeyedQuery, in_key_lab, key_select
from service.store.loaders import batch_trajectories, load_trajectories
from service.store.models.blobs import Blob
from service.store.models.demonstrators import Demonstration, Demonstrator, Task, TrueReward
from service.store.models.jobs import Job, Reward
from service.store.models.mdps import Mdp
from service.store.owned import not_found

MEDIA_TYPES: dict[str, str] = {
    "json": "application/json",
    "npy": "application/octet-stream",
    "csv": "text/csv; charset=utf-8",
    "png": "image/png",
}


INLINE_FORMATS = {"json", "png"}
"""Formats a browser can show: sent ``inline``; the others as ``attachment``."""


@dataclass(frozen=True)
class Download:
    """A file to send, or (``content`` None) a 304 because the client's copy has this ETag."""

    content: bytes | None
    media_type: str
    filename: str
    disposition: str
    etag: str | None


def download(
    session: Session,
    ctx: RewardContext,
    *,
    fmt: Format,
    quantity: Quantity,
    overlay: Overlay,
    if_none_match: str | None,
) -> Download:
    """One reward, value function or policy as `fmt`; the ETag is checked before any array is read or drawn.

    The ETag hashes the stored blob's SHA-256 with everything else the bytes depend on (reward id, format,
    quantity, and for csv/png the layout; for png the title, the demonstration batches drawn and the scale).
    """
    blob_id = blob_id_of(ctx.row, quantity)
    if overlay != "none" and fmt != "png":
        raise Unprocessable(
            "overlay draws on a heatmap: use it with format=png.",
            errors=[{"pointer": "", "parameter": "overlay", "message": "only applies to format=png"}],
        )
    variant: list[str] = [ctx.row.id, fmt, quantity]
    if fmt in ("csv", "png"):
        variant.append(json.dumps(ctx.mdp.layout, sort_keys=True))
    if fmt == "png":
        _check_drawable(ctx, quantity)
        variant += [_title(ctx, quantity), ",".join(_demonstration_ids(session, ctx.task_ids, overlay))]
        variant.append(repr(FIXED_SCALES.get(quantity)))
    filename = exports.download_filename(
        demonstrator=ctx.demonstrator.name,
        task=ctx.task.name if ctx.task else None,
        quantity=quantity,
        ext=fmt,
    )

    def content(values: np.ndarray) -> bytes:
        """The file of the loaded array."""
        if fmt == "json":
            return exports.to_json(values, reward_id=ctx.row.id, quantity=quantity).encode()
        if fmt == "png":
            return _heatmap(session, ctx, values, quantity=quantity, overlay=overlay)
        return array_file(values, fmt=fmt, layout=ctx.layout, quantity=quantity)

    return blob_download(
        session,
        blob_id,
        fmt=fmt,
        filename=filename,
        variant=variant,
        if_none_match=if_none_match,
        make=content,
    )


def blob_download(
    session: Session,
    blob_id: str,
    *,
    fmt: Format,
    filename: str,
    variant: Sequence[str],
    if_none_match: str | None,
    make: Callable[[np.ndarray], bytes],
) -> Download:
    """Stored array `blob_id` as a `fmt` file made by `make`, with its media type, disposition and ETag (the blob's
    SHA-256 hashed with `variant`); a 304 when ``If-None-Match`` names that ETag, before the array is read."""
    etag = exports.etag_for(blob_sha256(session, blob_id), *variant)
    disposition = "inline" if fmt in INLINE_FORMATS else "attachment"
    if etag_matches(if_none_match, etag):
        return Download(None, MEDIA_TYPES[fmt], filename, disposition, etag)
    return Download(make(get_array(session, blob_id)), MEDIA_TYPES[fmt], filename, disposition, etag)


def array_file(
    values: np.ndarray, *, fmt: Literal["npy", "csv"], layout: Layout | None, quantity: str
) -> bytes:
    """Per-state values as a float32 ``.npy`` or as CSV (``state[,x,y,channel],<quantity>``)."""
    if fmt == "npy":
        return exports.to_npy(values)
    return exports.to_csv(values, layout=layout, quantity=quantity).encode()


TRUE_REWARD = "true_reward"
"""The quantity a true reward's files are named by: its CSV column, ``…_true-reward.csv``."""


def true_reward_download(
    session: Session, task: Task, row: TrueReward, *, fmt: Literal["npy", "csv"], if_none_match: str | None
) -> Download:
    """A task's true reward as an npy or csv file, made, named and tagged as a learned reward's download is."""
    mdp = session.get_one(Mdp, task.mdp_id)
    demonstrator = session.get_one(Demonstrator, task.demonstrator_id)
    layout = Layout(**mdp.layout) if mdp.layout else None
    variant = [task.id, fmt, TRUE_REWARD] + ([json.dumps(mdp.layout, sort_keys=True)] if fmt == "csv" else [])
    filename = exports.download_filename(
        demonstrator=demonstrator.name, task=task.name, quantity=TRUE_REWARD, ext=fmt
    )
    return blob_download(
        session,
        row.blob_id,
        fmt=fmt,
        filename=filename,
        variant=variant,
        if_none_match=if_none_match,
        make=lambda values: array_file(values, fmt=fmt, layout=layout, quantity=TRUE_REWARD),
    )


STORED_FORMATS = {"npy", "json"}
"""Formats made from the stored bytes and names alone (no MDP, no drawing): `keyed_stored_file` reads them."""


@cache
def keyed_stored_file(quantity: Quantity, *, with_data: bool) -> KeyedQuery:
    """The key check (`service.store.keys.key_select`) and what an npy or json download of reward
    ``:reward_id`` needs, in one statement: the reward's id and task (``reward_id``, ``reward_task_id``), the
    names its file is called by (``task_name``, ``demonstrator_name``) and the `quantity` blob's ``blob_id``,
    ``blob_sha256``, ``blob_dtype``, ``blob_shape`` and, with `with_data`, its bytes ``blob_data``; all NULL
    unless the reward is in the key's lab. Built once per quantity and with or without the bytes."""
    blob_column = {
        "reward": Reward.reward_blob_id,
        "value": Reward.value_blob_id,
        "policy": Reward.policy_blob_id,
        "uncertainty": Reward.uncertainty_blob_id,
        "evidence": Reward.evidence_blob_id,
    }[quantity]
    columns: list[ColumnElement[Any]] = [
        Reward.id.label("reward_id"),
        Reward.task_id.label("reward_task_id"),
        Task.name.label("task_name"),
        Demonstrator.name.label("demonstrator_name"),
        Blob.id.label("blob_id"),
        Blob.sha256.label("blob_sha256"),
        Blob.dtype.label("blob_dtype"),
        Blob.shape.label("blob_shape"),
    ]
    if with_data:
        columns.append(Blob.data.label("blob_data"))
    return (
        key_select()
        .add_columns(*columns)
        .outerjoin(Reward, and_(Reward.id == bindparam("reward_id"), in_key_lab(Reward.lab_id)))
        .outerjoin(Job, Job.id == Reward.job_id)
        .outerjoin(Demonstrator, Demonstrator.id == Job.demonstrator_id)
        .outerjoin(Task, Task.id == Reward.task_id)
        .outerjoin(Blob, Blob.id == blob_column)
    )


BLOB_DATA = select(Blob.data).where(Blob.id == bindparam("blob_id"))
"""The stored bytes of blob ``:blob_id`` (for a stored download whose first read left them out)."""


@dataclass(frozen=True)
class StoredFile:
    """An npy or json download of a stored array, from a `keyed_stored_file` row (`stored_file` checks it): the
    same ETag and file name as `download` gives, and the file made from the stored bytes as they are."""

    row: Row[Any]
    fmt: Format
    quantity: Quantity
    etag: str
    filename: str

    def answer(self, content: bytes | None) -> Download:
        """The download with `content` (None: a 304, the client's copy has this ETag)."""
        disposition = "inline" if self.fmt in INLINE_FORMATS else "attachment"
        return Download(content, MEDIA_TYPES[self.fmt], self.filename, disposition, self.etag)

    def content(self, data: bytes) -> bytes:
        """The file of the stored bytes `data`: npy sends them behind a header; json lists the values (this
        costs time on a large array, so the async route runs it in a thread)."""
        dtype, shape = self.row.blob_dtype, self.row.blob_shape
        if self.fmt == "npy":
            return exports.npy_from_stored(data, dtype=dtype, shape=shape)
        values = np.frombuffer(data, dtype=np.dtype(dtype)).reshape(shape)
        return exports.to_json(values, reward_id=self.row.reward_id, quantity=self.quantity).encode()


def stored_file(found: Row[Any], reward_id: str, *, fmt: Format, quantity: Quantity) -> StoredFile:
    """The download a `keyed_stored_file` row describes; 404 if the key's lab has no reward `reward_id`, 409
    for a quantity the reward lacks (`not_stored`), as `download` answers."""
    if fmt not in STORED_FORMATS:
        raise ValueError(f"stored files are {sorted(STORED_FORMATS)}, not {fmt!r}")
    if found.reward_id is None:
        raise not_found("reward", reward_id)
    if found.blob_id is None:
        raise not_stored(quantity, found.reward_id)
    filename = exports.download_filename(
        demonstrator=found.demonstrator_name,
        task=found.task_name if found.reward_task_id else None,
        quantity=quantity,
        ext=fmt,
    )
    etag = exports.etag_for(found.blob_sha256, found.reward_id, fmt, quantity)
    return StoredFile(found, fmt, quantity, etag, filename)


def demonstrations_csv(session: Session, task: Task, batch: Demonstration) -> Download:
    """One demonstration batch as the CSV its upload route takes (trajectories numbered in upload order), named
    ``patient-07_walk-up_demonstrations_trj_….csv``."""
    demonstrator = session.get_one(Demonstrator, task.demonstrator_id)
    stem = exports.download_filename(
        demonstrator=demonstrator.name, task=task.name, quantity="demonstrations", ext="csv"
    ).removesuffix(".csv")
    trajectories = batch_trajectories(session, batch)
    content = csv_demonstrations.to_csv((str(j), t.states, t.actions) for j, t in enumerate(trajectories))
    return Download(content, MEDIA_TYPES["csv"], f"{stem}_{batch.id}.csv", "attachment", etag=None)


def etag_matches(if_none_match: str | None, etag: str) -> bool:
    """Whether an ``If-None-Match`` header names `etag` (or is ``*``); weak tags compare by value (RFC 9110)."""
    if not if_none_match:
        return False
    tags = {tag.strip().removeprefix("W/") for tag in if_none_match.split(",")}
    return "*" in tags or etag in tags


def matrix_download(session: Session, job: Job, matrix: ComparisonMatrix) -> Download:
    """The comparison matrix drawn as an annotated PNG, titled with the demonstrator's name."""
    demonstrator = session.get_one(Demonstrator, job.demonstrator_id)
    png = images.matrix_png(
        np.asarray(matrix.matrix), labels=matrix.labels, title=f"Pearson r — {demonstrator.name}"
    )
    filename = exports.download_filename(
        demonstrator=demonstrator.name, task="all tasks", quantity="pearson", ext="png"
    )
    return Download(png, MEDIA_TYPES["png"], filename, "inline", etag=None)


def _check_drawable(ctx: RewardContext, quantity: Quantity) -> None:
    """409 unless a heatmap can be drawn: the MDP needs a layout, and a policy has no single value per state."""
    if ctx.layout is None:
        raise Conflict(
            f"MDP {ctx.mdp.id} has no layout, so its states cannot be drawn as a picture; download "
            "format=csv, npy or json, or create the MDP with a layout (width, height, channels)."
        )
    if quantity == "policy":
        raise Conflict(
            "A policy has one probability per action in each state, which one heatmap cannot show; "
            "download it as npy, csv or json, or draw quantity=value."
        )


def _title(ctx: RewardContext, quantity: Quantity) -> str:
    """The heatmap's title: ``task — demonstrator``, naming the quantity unless it is the reward."""
    return ctx.label if quantity == "reward" else f"{ctx.label} ({quantity})"


def _demonstration_ids(session: Session, task_ids: list[str], overlay: Overlay) -> list[str]:
    """Ids of the demonstration batches an overlay draws (none without an overlay)."""
    if overlay == "none":
        return []
    return list(
        session.execute(
            select(Demonstration.id)
            .where(Demonstration.task_id.in_(task_ids))
            .order_by(Demonstration.created_at, Demonstration.id)
        ).scalars()
    )


FIXED_SCALES: dict[str, images.Scale] = {
    "evidence": images.Scale(0.0, 1.0, {0.0: "elsewhere", 0.5: "next to a visit", 1.0: "visited"}),
}
"""Quantities of known levels drawn on one fixed colour scale (evidence: `metairl_engine.evidence`'s 1, ½, 0),
so a colour means the same level on every map, whatever levels one map happens to hold."""


def _heatmap(
    session: Session, ctx: RewardContext, values: np.ndarray, *, quantity: Quantity, overlay: Overlay
) -> bytes:
    """The PNG heatmap, with the demonstrated trajectories behind the reward drawn on it for overlay=demos."""
    layout = ctx.layout
    assert layout is not None  # _check_drawable ran first
    trajectories = None
    if overlay == "demos":
        trajectories = [t.states for task_id in ctx.task_ids for t in load_trajectories(session, task_id)]
    return images.heatmap_png(
        values,
        layout=layout,
        title=_title(ctx, quantity),
        trajectories=trajectories,
        colorbar_label=quantity,
        scale=FIXED_SCALES.get(quantity),
    )
