"""MDPs: build and validate with the engine, store arrays as blobs, read metadata without the arrays."""

from __future__ import annotations

from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from metairl_engine import MDP, Layout
from metairl_engine.grids import grid_mdp
from service.domain.mdps import ExplicitMdpIn, GridMdpIn
from service.store.blobs import put_array
from service.store.ids import new_id
from service.store.models.blobs import Blob
from service.store.models.mdps import Mdp
from service.store.owned import get_owned
from service.store.paging import PageParams, RowPage, paginate


def build_explicit(body: ExplicitMdpIn) -> MDP:
    """The engine's MDP from a JSON body (raises `InvalidInput` with request pointers)."""
    transitions = body.transitions.model_dump(exclude={"kind"})
    layout = Layout(**body.layout.model_dump()) if body.layout else None
    return MDP.build(
        gamma=body.gamma,
        n_states=body.n_states,
        n_actions=body.n_actions,
        features=body.features,
        layout=layout,
        **transitions,
    )


def build_grid(body: GridMdpIn) -> tuple[MDP, dict[str, Any]]:
    """The grid MDP built server side, and the parameters to remember."""
    params = body.model_dump(exclude={"kind", "name", "gamma"})
    mdp = grid_mdp(**params, gamma=body.gamma)
    return mdp, params | {"moves": body.moves or (8 if body.velocity else 4)}


def summarise(mdp: MDP) -> dict[str, Any]:
    """Cheap facts about an MDP for its GET: transition count, absorbing and unreachable states, feature range."""
    states = np.arange(mdp.n_states)
    if mdp.next_state is not None:
        src = np.repeat(states, mdp.n_actions)
        dst = mdp.next_state.ravel().astype(np.int64)
        prob = np.ones(dst.shape)
    else:
        assert mdp.sparse is not None
        keep = mdp.sparse.p > 0
        src, dst, prob = (
            mdp.sparse.s[keep].astype(np.int64),
            mdp.sparse.next[keep].astype(np.int64),
            mdp.sparse.p[keep],
        )
    stay = np.bincount(src[dst == src], weights=prob[dst == src], minlength=mdp.n_states)
    entered = np.bincount(dst[dst != src], minlength=mdp.n_states)
    out: dict[str, Any] = {
        "n_transitions": int(src.size),
        "absorbing_states": int(np.sum(stay >= mdp.n_actions - 1e-4)),
        "unreachable_states": int(np.sum(entered == 0)),
    }
    if mdp.features is not None:
        out["feature_min"] = float(mdp.features.min())
        out["feature_max"] = float(mdp.features.max())
    return out


def create_mdp(
    session: Session, *, lab_id: str, name: str, source: str, mdp: MDP, grid: dict[str, Any] | None = None
) -> Mdp:
    """Add a validated MDP (row and array blobs, flushed, not committed)."""
    row = Mdp(
        id=new_id("mdp"),
        lab_id=lab_id,
        name=name,
        source=source,
        n_states=mdp.n_states,
        n_actions=mdp.n_actions,
        n_features=None if mdp.features is None else mdp.n_features,
        gamma=mdp.gamma,
        transitions="deterministic" if mdp.is_deterministic else "sparse",
        layout=None if mdp.layout is None else vars(mdp.layout),
        grid=grid,
        summary=summarise(mdp),
        array_blobs={key: put_array(session, arr, lab_id=lab_id) for key, arr in mdp.arrays().items()},
    )
    session.add(row)
    session.flush()
    return row


def array_blobs(session: Session, rows: list[Mdp]) -> dict[str, Any]:
    """Blob id → (id, shape, dtype, sha256) of the MDPs' arrays: their metadata, never their data."""
    ids = [blob_id for row in rows for blob_id in row.array_blobs.values()]
    blobs = session.execute(
        select(Blob.id, Blob.shape, Blob.dtype, Blob.sha256).where(Blob.id.in_(ids))
    ).all()
    return {b.id: b for b in blobs}


def get_mdp(session: Session, mdp_id: str, *, lab_id: str) -> Mdp:
    """The lab's MDP row, or 404."""
    return get_owned(session, Mdp, mdp_id, lab_id=lab_id, what="MDP")


def list_mdps(session: Session, *, lab_id: str, page: PageParams) -> RowPage[Mdp]:
    """One page of the lab's MDPs, newest first."""
    return paginate(session, select(Mdp).where(Mdp.lab_id == lab_id), page, key=(Mdp.created_at, Mdp.id))
