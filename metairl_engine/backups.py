"""Q from the VR function (paper eq. 6) and the Bellman backups V = backup_a Q (eq. 7 and its variants).

`QRows` precomputes, for a fixed list of (task, state) rows, how to read Q(s, ·) off the VR values:
a GATHER of f[next_state] when every task is deterministic, one sparse (CSR) matmul otherwise. Rows of
several tasks are batched in one op; the VR values are only ever needed on a subset U of the states
(``columns`` maps a state to its position in U, one map per task or one shared by all).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
import torch

from metairl_engine.config import Backup
from metairl_engine.mdp import MDP
from metairl_engine.planning import transition_matrix


def backup(q: torch.Tensor, *, kind: Backup, bgi_k: float) -> torch.Tensor:
    """V(s) from Q(s, ·) over the last axis: max (eq. 7), logsumexp (MaxEnt) or (1/k)·logsumexp(k·Q) (BGI)."""
    if kind == "max":  # max, not amax: its backward scatters to one argmax instead of sharing among ties
        return q.max(dim=-1).values
    if kind == "logsumexp":
        return torch.logsumexp(q, dim=-1)
    return torch.logsumexp(bgi_k * q, dim=-1) / bgi_k


class QRows:
    """Q_t(s, ·) = Σ_s' P_t(s'|s, ·) f_t(s') for fixed rows (task t, state s) (eq. 6); no state loop."""

    def __init__(
        self,
        mdps: Sequence[MDP],
        tasks: np.ndarray,
        states: np.ndarray,
        *,
        columns: np.ndarray,
        n_columns: int,
    ):
        n_actions = mdps[0].n_actions
        self.n_rows, self.n_actions = len(states), n_actions
        columns = np.broadcast_to(columns, (len(mdps), columns.shape[-1]))  # one map per task, or one for all
        self.index: torch.Tensor | None = None
        self.matrix: torch.Tensor | None = None  # P's rows as CSR, and its transpose for the backward pass
        self.transposed: torch.Tensor | None = None
        if all(m.next_state is not None for m in mdps):
            table = np.stack([m.next_state for m in mdps if m.next_state is not None])  # (T, S, A)
            nxt = table[tasks, states]  # (N, A)
            self.index = torch.from_numpy(tasks[:, None] * n_columns + columns[tasks[:, None], nxt]).reshape(
                -1
            )
            return
        empty = np.zeros(0, dtype=np.int64)  # no rows at all (no hold-out): an empty matrix, not an error
        rows, cols, vals = [empty], [empty], [np.zeros(0)]
        for t, mdp in enumerate(mdps):
            mine = np.flatnonzero(tasks == t)
            if mine.size == 0:
                continue
            sa = (states[mine, None] * n_actions + np.arange(n_actions)).reshape(-1)
            sub = transition_matrix(mdp)[sa].tocoo()
            rows.append(((mine[:, None] * n_actions + np.arange(n_actions)).reshape(-1))[sub.row])
            cols.append(t * n_columns + columns[t, sub.col])
            vals.append(sub.data)
        matrix = sp.csr_matrix(
            (np.concatenate(vals).astype(np.float32), (np.concatenate(rows), np.concatenate(cols))),
            shape=(self.n_rows * n_actions, len(mdps) * n_columns),
        )
        self.matrix = _torch_csr(matrix)
        self.transposed = _torch_csr(matrix.T.tocsr())

    def to(self, device: torch.device) -> QRows:
        """These rows with their gather index or sparse matrix on ``device`` (moved in place; returns self)."""
        if self.index is not None:
            self.index = self.index.to(device)
        if self.matrix is not None and self.transposed is not None:
            self.matrix, self.transposed = self.matrix.to(device), self.transposed.to(device)
        return self

    def __call__(self, f: torch.Tensor) -> torch.Tensor:
        """Q (N, A) for the rows, from VR values ``f`` (T, |U|).

        ``index_select``, not ``flat[index]``: its backward is an ``index_add``, several times cheaper than the
        accumulating ``index_put`` of advanced indexing.
        """
        flat = f.reshape(-1)
        if self.index is not None:
            return flat.index_select(0, self.index).reshape(self.n_rows, self.n_actions)
        assert self.matrix is not None and self.transposed is not None
        q = _SparseProduct.apply(flat.unsqueeze(1), self.matrix, self.transposed)
        return q.reshape(self.n_rows, self.n_actions)


def _torch_csr(matrix: sp.csr_matrix) -> torch.Tensor:
    """The torch CSR tensor of a scipy CSR matrix (torch's warning that CSR support is beta silenced)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sparse CSR tensor support is in beta state")
        return torch.sparse_csr_tensor(
            torch.from_numpy(matrix.indptr.astype(np.int64)),
            torch.from_numpy(matrix.indices.astype(np.int64)),
            torch.from_numpy(matrix.data),
            size=matrix.shape,
            check_invariants=False,  # scipy's CSR is valid by construction
        )


class _SparseProduct(torch.autograd.Function):
    """y = P·x for a constant CSR matrix P; the backward pass is Pᵀ·g with Pᵀ kept as CSR too.

    Both are one MKL CSR product; torch's own backward of ``sparse.mm`` on a COO P transposes and
    re-coalesces P every step, and its COO forward is ~20× slower than CSR (benchmarks/RESULTS.md).
    """

    @staticmethod
    def forward(ctx: Any, x: torch.Tensor, matrix: torch.Tensor, transposed: torch.Tensor) -> torch.Tensor:
        ctx.transposed = transposed
        return matrix @ x

    @staticmethod
    def backward(ctx: Any, grad: torch.Tensor) -> tuple[torch.Tensor, None, None]:
        return ctx.transposed @ grad, None, None


def successor_pairs(
    mdps: Sequence[MDP], tasks: np.ndarray, states: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(task, state) of every state reachable in one step from each row (task, state), repeats included."""
    found_tasks, found = [np.zeros(0, dtype=np.int64)], [np.zeros(0, dtype=np.int64)]
    for t, mdp in enumerate(mdps):
        mine = states[tasks == t]
        if mine.size == 0:
            continue
        if mdp.next_state is not None:
            reached = mdp.next_state[mine].reshape(-1)
        else:
            sa = (mine[:, None] * mdp.n_actions + np.arange(mdp.n_actions)).reshape(-1)
            reached = transition_matrix(mdp)[sa].indices
        found.append(reached.astype(np.int64))
        found_tasks.append(np.full(len(reached), t, dtype=np.int64))
    return np.concatenate(found_tasks), np.concatenate(found)


def successors(mdps: Sequence[MDP], tasks: np.ndarray, states: np.ndarray) -> np.ndarray:
    """Sorted unique states reachable in one step from the rows (task, state): where Q needs f."""
    return np.unique(successor_pairs(mdps, tasks, states)[1])
