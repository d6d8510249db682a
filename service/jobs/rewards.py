"""What a job produced: its reward rows (written by the worker with `add_reward`), and for the API the
reward listings, downloads, comparisons, the Pearson matrix and key states (docs/api.md, "Rewards" and
"Comparisons").

The logic behind service/api/routes/rewards.py and service/api/routes/comparisons.py: rows and arrays come
from the database, files from `service.files.exports` and `service.files.images`, numbers from
`metairl_engine.metrics` (numpy/scipy, never torch). Errors are `ApiError`s. Every reward is looked up in the
caller's lab (404 otherwise).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np
from sqlalchemy import ColumnElement, Row, and_, bindparam, select
from sqlalchemy.orm import Session

from metairl_engine.mdp import Layout
from metairl_engine.motion.readout import BASELINE_CAVEAT

if TYPE_CHECKING:
    from metairl_engine.distances import Interval as Bootstrapped

from service.domain.comparisons import (
    ComparedSide,
    ComparisonIn,
    ComparisonOut,
    DynamicsDistances,
    Interval,
    OtherSide,
)
from service.domain.rewards import (
    ComparisonMatrix,
    Format,
    JobRewards,
    KeyState,
    KeyStates,
    Overlay,
    Quantity,
    RewardRef,
    RewardSummary,
    reward_links,
)
from service.files import exports, images
from service.problems import Conflict, Unprocessable
from service.store.blobs import blob_sha256, get_array, put_array
from service.store.ids import new_id
from service.store.keys import KeyedQuery, in_key_lab, key_select
from service.store.loaders import load_mdp, load_trajectories, load_true_reward
from service.store.models.blobs import Blob
from service.store.models.demonstrators import Demonstration, Demonstrator, Task
from service.store.models.job_status import JobStatus
from service.store.models.jobs import Job, Reward
from service.store.models.mdps import Mdp
from service.store.owned import get_owned, not_found

MEDIA_TYPES: dict[str, str] = {
    "json": "application/json",
    "npy": "application/octet-stream",
    "csv": "text/csv; charset=utf-8",
    "png": "image/png",
}
INLINE_FORMATS = {"json", "png"}
"""Formats a browser can show: sent ``inline``; the others as ``attachment``."""


@dataclass(frozen=True)
class RewardContext:
    """A reward row with what names and draws it: job, task (None for the baseline), demonstrator, layout."""

    row: Reward
    job: Job
    task: Task | None
    demonstrator: Demonstrator
    mdp: Mdp

    @property
    def layout(self) -> Layout | None:
        """How the states tile a picture, if the MDP has a layout."""
        return Layout(**self.mdp.layout) if self.mdp.layout else None

    @property
    def task_ids(self) -> list[str]:
        """The tasks whose demonstrations are behind this reward: its task, or every task of the job."""
        return [self.task.id] if self.task else list(self.job.task_ids)

    @property
    def label(self) -> str:
        """``task — demonstrator``, or ``baseline — demonstrator``."""
        return f"{self.task.name if self.task else 'baseline'} — {self.demonstrator.name}"

    def describe(self) -> ComparedSide:
        """This reward as one side of a comparison."""
        return ComparedSide(
            kind="reward",
            label=self.label,
            reward_id=self.row.id,
            job_id=self.job.id,
            task_id=self.row.task_id,
            demonstrator_id=self.demonstrator.id,
        )


@dataclass(frozen=True)
class Download:
    """A file to send, or (``content`` None) a 304 because the client's copy has this ETag."""

    content: bytes | None
    media_type: str
    filename: str
    disposition: str
    etag: str | None


def add_reward(
    session: Session,
    job: Job,
    *,
    ordinal: int,
    n_actions: int,
    reward: np.ndarray,
    value: np.ndarray | None = None,
    policy: np.ndarray | None = None,
) -> Reward:
    """Add one result row of `job` (ordinal 0: the baseline; i + 1: task i) with its arrays and summary.

    The summary is computed here, once, so listing a job's rewards never loads their arrays.
    """
    task_id = job.task_ids[ordinal - 1] if ordinal else None
    lab_id = job.lab_id
    row = Reward(
        id=new_id("rwd"),
        lab_id=lab_id,
        job_id=job.id,
        ordinal=ordinal,
        kind="task" if task_id else "baseline",
        task_id=task_id,
        n_states=int(reward.shape[0]),
        n_actions=n_actions,
        reward_blob_id=put_array(session, reward, lab_id=lab_id),
        value_blob_id=None if value is None else put_array(session, value, lab_id=lab_id),
        policy_blob_id=None if policy is None else put_array(session, policy, lab_id=lab_id),
        summary=exports.summary(reward),
    )
    session.add(row)
    return row


def reward_context(session: Session, reward_id: str, *, lab_id: str) -> RewardContext:
    """The lab's reward `reward_id` with its job, task, demonstrator and MDP; 404 for another lab's."""
    return _context(session, get_owned(session, Reward, reward_id, lab_id=lab_id, what="reward"))


def job_rewards(session: Session, job: Job, *, exclude_top_truth: bool) -> JobRewards:
    """The baseline and every task reward with summary, truth scores (against the current true reward), links."""
    refs = []
    for row in _job_reward_rows(session, job):
        ctx = _context(session, row)
        truth = load_true_reward(session, row.task_id) if row.task_id else None
        values = None if truth is None else get_array(session, row.reward_blob_id)
        refs.append(
            RewardRef(
                reward_id=row.id,
                kind="task" if ctx.task else "baseline",
                task_id=row.task_id,
                task_name=ctx.task.name if ctx.task else None,
                n_states=row.n_states,
                n_actions=row.n_actions,
                summary=RewardSummary.model_validate(row.summary),
                truth_pearson=None if values is None or truth is None else metrics().pearson(values, truth),
                truth_pearson_excluding_top=(
                    _pearson_below_top(values, truth) if exclude_top_truth and values is not None else None
                ),
                links=reward_links(row.id, drawable=ctx.layout is not None, task=ctx.task is not None),
                note=None if ctx.task else baseline_note(job, ctx.layout),
            )
        )
    return JobRewards(job_id=job.id, demonstrator_id=job.demonstrator_id, baseline=refs[0], tasks=refs[1:])


MEAN_OF_TASKS = (
    'No baseline reward was learned (sharing "none", or the maxent method): this is the mean of the task '
    "rewards, a summary of them rather than an estimate of the demonstrator's inherent reward."
)


def baseline_note(job: Job, layout: Layout | None) -> str | None:
    """What a reader of this job's baseline must know: that it is no estimate (sharing none, maxent), or its
    caveat on a velocity grid (out-and-back movements do not identify all of it; docs/motion.md)."""
    if job.config.get("sharing") == "none" or job.config.get("method") == "maxent":
        return MEAN_OF_TASKS
    if layout is not None and layout.channels == 8:
        return BASELINE_CAVEAT
    return None


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
    quantity, and for csv/png the layout; for png the title and the demonstration batches drawn).
    """
    blob_id = _blob_id(ctx.row, quantity)
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
    etag = exports.etag_for(blob_sha256(session, blob_id), *variant)
    filename = exports.download_filename(
        demonstrator=ctx.demonstrator.name,
        task=ctx.task.name if ctx.task else None,
        quantity=quantity,
        ext=fmt,
    )
    disposition = "inline" if fmt in INLINE_FORMATS else "attachment"
    if etag_matches(if_none_match, etag):
        return Download(None, MEDIA_TYPES[fmt], filename, disposition, etag)
    values = get_array(session, blob_id)
    if fmt == "npy":
        content = exports.to_npy(values)
    elif fmt == "csv":
        content = exports.to_csv(values, layout=ctx.layout, quantity=quantity).encode()
    elif fmt == "json":
        content = exports.to_json(values, reward_id=ctx.row.id, quantity=quantity).encode()
    else:
        content = _heatmap(session, ctx, values, quantity=quantity, overlay=overlay)
    return Download(content, MEDIA_TYPES[fmt], filename, disposition, etag)


def metrics() -> ModuleType:
    """`metairl_engine.metrics`, imported on first use: it loads scipy (~70 MB), which an API process that
    only serves jobs and downloads never needs."""
    import metairl_engine.metrics

    return metairl_engine.metrics


def dynamics() -> ModuleType:
    """`metairl_engine.distances` (EPIC and STARC under the MDP's transitions), imported on first use (scipy)."""
    import metairl_engine.distances

    return metairl_engine.distances


def planning() -> ModuleType:
    """`metairl_engine.planning` (transition matrices), imported on first use (scipy)."""
    import metairl_engine.planning

    return metairl_engine.planning


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
    for the baseline's (absent) value function or policy, as `download` answers."""
    if fmt not in STORED_FORMATS:
        raise ValueError(f"stored files are {sorted(STORED_FORMATS)}, not {fmt!r}")
    if found.reward_id is None:
        raise not_found("reward", reward_id)
    if found.blob_id is None:
        raise _baseline_has_no(quantity, found.reward_id)
    filename = exports.download_filename(
        demonstrator=found.demonstrator_name,
        task=found.task_name if found.reward_task_id else None,
        quantity=quantity,
        ext=fmt,
    )
    etag = exports.etag_for(found.blob_sha256, found.reward_id, fmt, quantity)
    return StoredFile(found, fmt, quantity, etag, filename)


def etag_matches(if_none_match: str | None, etag: str) -> bool:
    """Whether an ``If-None-Match`` header names `etag` (or is ``*``); weak tags compare by value (RFC 9110)."""
    if not if_none_match:
        return False
    tags = {tag.strip().removeprefix("W/") for tag in if_none_match.split(",")}
    return "*" in tags or etag in tags


def compare(session: Session, body: ComparisonIn, *, lab_id: str) -> ComparisonOut:
    """Pearson, Spearman and EPIC distance of reward `a` and side `b` on all or the demonstrated states, and
    EPIC and STARC with the dynamics of a's MDP."""
    a = _body_reward(session, body.a.reward_id, lab_id=lab_id, pointer="/a/reward_id")
    x_all = get_array(session, a.row.reward_blob_id)
    y_all, side, b_tasks = _other_side(session, body.b, n_states=a.row.n_states, lab_id=lab_id)
    tasks = [*a.task_ids, *b_tasks]
    mask = visited_states(session, tasks, a.row.n_states) if body.states == "visited" else None
    x, y = (x_all[mask], y_all[mask]) if mask is not None else (x_all, y_all)
    return ComparisonOut(
        pearson=metrics().pearson(x, y),
        spearman=metrics().spearman(x, y),
        epic_distance=metrics().epic_distance(x, y),
        states=body.states,
        n_states=a.row.n_states,
        n_compared=int(x.size),
        dynamics=dynamics_distances(session, a, x_all, y_all, body=body, tasks=tasks, mask=mask),
        a=a.describe(),
        b=side,
    )


def dynamics_distances(
    session: Session,
    a: RewardContext,
    x: np.ndarray,
    y: np.ndarray,
    *,
    body: ComparisonIn,
    tasks: list[str],
    mask: np.ndarray | None,
) -> DynamicsDistances:
    """EPIC and STARC of the two rewards under a's MDP, states weighted uniformly or by the demonstrations'
    occupancy (and only the compared states)."""
    mdp = load_mdp(session, a.mdp.id)
    weights = np.ones(mdp.n_states)
    if body.weights == "occupancy":
        weights = state_occupancy(session, tasks, mdp.n_states)
    if mask is not None:
        weights = weights * mask
    found = dynamics().distances(
        x,
        y,
        transitions=planning().transition_matrix(mdp),
        gamma=mdp.gamma,
        n_actions=mdp.n_actions,
        state_weights=weights,
        bootstrap=body.bootstrap,
    )

    def interval(i: Bootstrapped | None) -> Interval | None:
        return None if i is None else Interval(low=i.low, high=i.high)

    return DynamicsDistances(
        epic=found.epic,
        epic_interval=interval(found.epic_interval),
        starc=found.starc,
        starc_interval=interval(found.starc_interval),
        weights=body.weights,
        n_bootstrap=found.n_bootstrap,
        mdp_id=a.mdp.id,
        gamma=mdp.gamma,
    )


def state_occupancy(session: Session, task_ids: list[str], n_states: int) -> np.ndarray:
    """How often each state occurs in the demonstrations of the given tasks."""
    counts = np.zeros(n_states)
    blob_ids = session.execute(
        select(Demonstration.states_blob_id).where(Demonstration.task_id.in_(task_ids))
    ).scalars()
    for blob_id in blob_ids:
        counts += np.bincount(get_array(session, blob_id).astype(np.int64), minlength=n_states)
    return counts


def visited_states(session: Session, task_ids: list[str], n_states: int) -> np.ndarray:
    """Boolean mask of the states that occur in any demonstration of the given tasks."""
    mask = np.zeros(n_states, dtype=bool)
    blob_ids = session.execute(
        select(Demonstration.states_blob_id).where(Demonstration.task_id.in_(task_ids))
    ).scalars()
    for blob_id in blob_ids:
        mask[get_array(session, blob_id)] = True
    return mask


def comparison_matrix(session: Session, job: Job) -> ComparisonMatrix:
    """Pearson r of every pair among the job's baseline and task rewards (metrics.pearson: 0 when undefined)."""
    rows = _job_reward_rows(session, job)
    values = [get_array(session, row.reward_blob_id) for row in rows]
    tasks = {t.id: t for t in session.execute(select(Task).where(Task.id.in_(job.task_ids))).scalars()}
    names = {t.id: t.name for t in tasks.values()}
    mdp = load_mdp(session, tasks[job.task_ids[0]].mdp_id)
    return ComparisonMatrix(
        job_id=job.id,
        labels=[names[row.task_id] if row.task_id else "baseline" for row in rows],
        reward_ids=[row.id for row in rows],
        task_ids=[row.task_id for row in rows],
        matrix=[[metrics().pearson(u, v) for v in values] for u in values],
        epic=dynamics()
        .pairwise_epic(
            values, transitions=planning().transition_matrix(mdp), gamma=mdp.gamma, n_actions=mdp.n_actions
        )
        .tolist(),
    )


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


def reward_key_states(session: Session, ctx: RewardContext, *, top: int) -> KeyStates:
    """The `top` states where the task reward departs most from its job's baseline; 409 for the baseline."""
    if ctx.task is None:
        raise Conflict(
            f"Reward {ctx.row.id} is the baseline, which key states are measured from; "
            "ask for the key states of one of the job's task rewards."
        )
    baseline_row = _job_reward_rows(session, ctx.job)[0]
    task_values = get_array(session, ctx.row.reward_blob_id).astype(np.float64)
    baseline = get_array(session, baseline_row.reward_blob_id).astype(np.float64)
    states = metrics().key_states(task_values, baseline, top=top)
    layout = ctx.layout
    coords = exports.grid_coordinates(states, layout) if layout else (None, None, None)
    return KeyStates(
        reward_id=ctx.row.id,
        baseline_reward_id=baseline_row.id,
        task_id=ctx.task.id,
        top=top,
        states=[
            KeyState(
                rank=rank + 1,
                state=int(s),
                x=None if coords[0] is None else int(coords[0][rank]),
                y=None if coords[1] is None else int(coords[1][rank]),
                channel=None if coords[2] is None else int(coords[2][rank]),
                reward=float(task_values[s]),
                baseline=float(baseline[s]),
                difference=float(task_values[s] - baseline[s]),
            )
            for rank, s in enumerate(states)
        ],
    )


def require_succeeded(job: Job) -> None:
    """409 unless the job has succeeded (only then does it have rewards)."""
    if job.status != JobStatus.SUCCEEDED:
        raise Conflict(f"Job {job.id} is {job.status}; rewards exist once it has succeeded.")


def _context(session: Session, row: Reward) -> RewardContext:
    """Load what names and draws `row`; the baseline is drawn on the MDP of the job's first task."""
    job = session.get_one(Job, row.job_id)
    task = session.get_one(Task, row.task_id) if row.task_id else None
    mdp_id = (task or session.get_one(Task, job.task_ids[0])).mdp_id
    return RewardContext(
        row=row,
        job=job,
        task=task,
        demonstrator=session.get_one(Demonstrator, job.demonstrator_id),
        mdp=session.get_one(Mdp, mdp_id),
    )


def _job_reward_rows(session: Session, job: Job) -> list[Reward]:
    """The job's reward rows, baseline first then tasks in the job's order."""
    return list(
        session.execute(select(Reward).where(Reward.job_id == job.id).order_by(Reward.ordinal)).scalars()
    )


def _blob_id(row: Reward, quantity: Quantity) -> str:
    """The blob holding `quantity` of `row`; 409 for the baseline's (absent) value function and policy."""
    blob_id = {"reward": row.reward_blob_id, "value": row.value_blob_id, "policy": row.policy_blob_id}[
        quantity
    ]
    if blob_id is None:
        raise _baseline_has_no(quantity, row.id)
    return blob_id


def _baseline_has_no(quantity: Quantity, reward_id: str) -> Conflict:
    """The 409 for the value function or policy of a baseline reward, which has neither."""
    return Conflict(
        f"Reward {reward_id} is the baseline, which has no {quantity}; ask a task's reward for its value or policy."
    )


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
        values, layout=layout, title=_title(ctx, quantity), trajectories=trajectories, colorbar_label=quantity
    )


def _pearson_below_top(values: np.ndarray, truth: np.ndarray | None) -> float | None:
    """Pearson r on the states whose true reward is below its maximum; None without truth or two such states."""
    if truth is None:
        return None
    below = truth < truth.max()
    return metrics().pearson(values, truth, mask=below) if below.sum() >= 2 else None


def _body_reward(session: Session, reward_id: str, *, lab_id: str, pointer: str) -> RewardContext:
    """A reward named in a request body: 422 at `pointer` when the lab has none with this id."""
    row = session.get(Reward, reward_id)
    if row is None or row.lab_id != lab_id:
        raise Unprocessable(
            f"No reward with id {reward_id!r}.",
            errors=[{"pointer": pointer, "message": "no reward with this id exists in your lab"}],
        )
    return _context(session, row)


def _other_side(
    session: Session, side: OtherSide, *, n_states: int, lab_id: str
) -> tuple[np.ndarray, ComparedSide, list[str]]:
    """Side b's values (checked to have `n_states`), its description, and the tasks whose visits count."""
    if side.reward_id is not None:
        ctx = _body_reward(session, side.reward_id, lab_id=lab_id, pointer="/b/reward_id")
        _check_length(ctx.row.n_states, n_states, pointer="/b/reward_id", what=f"reward {ctx.row.id}")
        return get_array(session, ctx.row.reward_blob_id), ctx.describe(), ctx.task_ids
    if side.task_id is not None:
        task = session.get(Task, side.task_id)
        if task is None or task.lab_id != lab_id:
            raise Unprocessable(
                f"No task with id {side.task_id!r}.",
                errors=[{"pointer": "/b/task_id", "message": "no task with this id exists in your lab"}],
            )
        truth = load_true_reward(session, task.id)
        if truth is None:
            raise Conflict(
                f"Task {task.id} has no true reward; PUT /v1/tasks/{task.id}/true-reward first, "
                "or post the values as b.values."
            )
        _check_length(truth.size, n_states, pointer="/b/task_id", what=f"the true reward of task {task.id}")
        demonstrator = session.get_one(Demonstrator, task.demonstrator_id)
        described = ComparedSide(
            kind="true_reward",
            label=f"{task.name} — {demonstrator.name} (true reward)",
            task_id=task.id,
            demonstrator_id=demonstrator.id,
        )
        return truth, described, [task.id]
    assert side.values is not None  # OtherSide holds exactly one of the three
    _check_length(len(side.values), n_states, pointer="/b/values", what="values")
    return np.asarray(side.values, dtype=np.float64), ComparedSide(kind="values", label="posted values"), []


def _check_length(length: int, n_states: int, *, pointer: str, what: str) -> None:
    """422 at `pointer` when side b does not have one value per state of reward a."""
    if length != n_states:
        message = f"{what} has {length} values; reward a has {n_states} states"
        raise Unprocessable(f"Cannot compare: {message}.", errors=[{"pointer": pointer, "message": message}])
