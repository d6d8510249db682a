"""Markov decision processes as the engine sees them: discount, features, transitions, optional layout.

numpy only (no torch) so that the API process can validate uploads with exactly the engine's rules.
State numbering for layouts: ``state = (channel * height + y) * width + x``, so a reward vector
reshapes to ``(channels, height, width)`` for drawing.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from metairl_engine.errors import Issue, check

FLOAT32_MAX = float(np.finfo(np.float32).max)
"""The largest finite float32: MDP arrays and rewards are stored as float32, so no finite value may exceed it."""

MAX_ISSUES = 20
"""At most this many issues are reported for one input; the first ones are the useful ones."""


def python_number(value: Any) -> Any:
    """A numpy scalar (``np.float32(0.9)``, ``np.int64(6)``, as a notebook's arithmetic gives) as the Python
    number it holds; anything else as it is, for the checks to judge."""
    return value.item() if isinstance(value, np.integer | np.floating) else value


@dataclass(frozen=True)
class Layout:
    """How states tile a picture: ``channels`` panels of ``height`` rows × ``width`` columns."""

    width: int
    height: int
    channels: int = 1

    def issues(self, n_states: int, pointer: str = "/layout") -> list[Issue]:
        """Problems with this layout for an MDP of ``n_states`` states."""
        out = [
            Issue(f"{pointer}/{name}", f"must be a positive integer, got {value}")
            for name, value in (("width", self.width), ("height", self.height), ("channels", self.channels))
            if value < 1
        ]
        if not out and self.width * self.height * self.channels != n_states:
            out.append(
                Issue(
                    pointer,
                    f"width × height × channels = {self.width}×{self.height}×{self.channels} = "
                    f"{self.width * self.height * self.channels}, but the MDP has {n_states} states",
                )
            )
        return out


@dataclass(frozen=True, eq=False)
class SparseTransitions:
    """Stochastic transitions as K triples: ``P(next[k] | s[k], a[k]) = p[k]``; all arrays shape (K,)."""

    s: np.ndarray
    a: np.ndarray
    next: np.ndarray
    p: np.ndarray


@dataclass(frozen=True, eq=False)
class MDP:
    """A finite MDP whose reward is to be learned; build it with `MDP.build`, which validates.

    Exactly one of ``next_state`` (deterministic, shape (S, A) int32) and ``sparse`` is set.
    ``features`` is (S, F) float32, or None for tabular one-hot features (never materialised:
    80,000 one-hot rows would take 25 GB).
    """

    n_states: int
    n_actions: int
    gamma: float
    features: np.ndarray | None = None
    next_state: np.ndarray | None = None
    sparse: SparseTransitions | None = None
    layout: Layout | None = None

    @classmethod
    def build(
        cls,
        *,
        gamma: float,
        n_states: int | None = None,
        n_actions: int | None = None,
        features: object = None,
        next_state: object = None,
        s: object = None,
        a: object = None,
        next: object = None,
        p: object = None,
        layout: Layout | None = None,
    ) -> MDP:
        """Coerce array-likes and validate everything; raises `InvalidInput` with JSON pointers into the request (docs/api.md, "MDPs").

        Pointers name the request fields: ``/gamma``, ``/features/3/1``, ``/transitions/next_state/7/2``,
        ``/transitions/p/12``, ``/layout``.
        """
        issues: list[Issue] = []
        gamma, n_states, n_actions = (python_number(v) for v in (gamma, n_states, n_actions))
        if not (isinstance(gamma, int | float) and 0.0 <= float(gamma) < 1.0):
            issues.append(Issue("/gamma", f"must be a number in [0, 1), got {gamma!r}"))
        det = next_state is not None
        if det == (s is not None or a is not None or next is not None or p is not None):
            issues.append(
                Issue("/transitions", "give either next_state (deterministic) or s, a, next, p (sparse)")
            )
            check(issues)

        ns_arr: np.ndarray | None = None
        sparse: SparseTransitions | None = None
        if det:
            ns_arr, more = _int_array(next_state, "/transitions/next_state", ndim=2)
            issues += more
            if ns_arr is not None:
                n_states = n_states if n_states is not None else ns_arr.shape[0]
                n_actions = n_actions if n_actions is not None else ns_arr.shape[1]
        else:
            parts = {}
            for name, raw in (("s", s), ("a", a), ("next", next)):
                arr, more = _int_array(raw, f"/transitions/{name}", ndim=1)
                issues += more
                parts[name] = arr
            p_arr, more = _float_array(p, "/transitions/p", ndim=1)
            issues += more
            if all(v is not None for v in parts.values()) and p_arr is not None:
                lengths = {k: len(v) for k, v in parts.items() if v is not None} | {"p": len(p_arr)}
                if len(set(lengths.values())) != 1:
                    issues.append(
                        Issue("/transitions", f"s, a, next and p must have equal lengths, got {lengths}")
                    )
                else:
                    assert parts["s"] is not None and parts["a"] is not None and parts["next"] is not None
                    sparse = SparseTransitions(parts["s"], parts["a"], parts["next"], p_arr)
                    if n_states is None:
                        n_states = int(max(parts["s"].max(initial=-1), parts["next"].max(initial=-1))) + 1
                    if n_actions is None:
                        n_actions = int(parts["a"].max(initial=-1)) + 1
        check(issues)
        assert n_states is not None and n_actions is not None
        if not isinstance(n_states, int) or n_states < 1:
            issues.append(Issue("/n_states", f"must be a positive integer, got {n_states!r}"))
        if not isinstance(n_actions, int) or n_actions < 1:
            issues.append(Issue("/n_actions", f"must be a positive integer, got {n_actions!r}"))
        check(issues)

        if ns_arr is not None:
            issues += _deterministic_issues(ns_arr, n_states, n_actions)
        if sparse is not None:
            issues += _sparse_issues(sparse, n_states, n_actions)
        feats: np.ndarray | None = None
        if features is not None:
            feats, more = _float_array(features, "/features", ndim=2)
            issues += more
            if feats is not None and feats.shape[0] != n_states:
                issues.append(
                    Issue("/features", f"has {feats.shape[0]} rows but the MDP has {n_states} states")
                )
            if feats is not None and feats.shape[1] < 1:
                issues.append(Issue("/features", "needs at least one column"))
        if layout is not None:
            issues += layout.issues(n_states)
        check(issues[:MAX_ISSUES])
        return cls(
            n_states=n_states,
            n_actions=n_actions,
            gamma=float(gamma),
            features=feats,
            next_state=ns_arr,
            sparse=sparse,
            layout=layout,
        )

    @property
    def is_deterministic(self) -> bool:
        """True when transitions are a next-state table (Q = f gathered, no matmul)."""
        return self.next_state is not None

    @property
    def n_features(self) -> int:
        """Width of the feature matrix (n_states for tabular one-hot features)."""
        return self.n_states if self.features is None else int(self.features.shape[1])

    @cached_property
    def _sparse_keys(self) -> np.ndarray:
        """Sorted int64 keys ``(s*A + a)*S + next`` of transitions with p > 0 (for step checks)."""
        assert self.sparse is not None
        t = self.sparse
        keep = t.p > 0
        keys = (t.s[keep].astype(np.int64) * self.n_actions + t.a[keep]) * self.n_states + t.next[keep]
        return np.sort(keys)

    def possible(self, states: np.ndarray, actions: np.ndarray, next_states: np.ndarray) -> np.ndarray:
        """Boolean mask: is ``P(next | state, action) > 0`` for each triple (inputs in range)."""
        if self.next_state is not None:
            return np.asarray(self.next_state[states, actions] == next_states)
        keys = (states.astype(np.int64) * self.n_actions + actions) * self.n_states + next_states
        sorted_keys = self._sparse_keys
        pos = np.searchsorted(sorted_keys, keys)
        pos = np.minimum(pos, len(sorted_keys) - 1)
        return np.asarray(sorted_keys[pos] == keys)

    def arrays(self) -> dict[str, np.ndarray]:
        """The MDP's arrays under the `.npz` upload's names (docs/api.md, "MDPs") (features omitted when tabular)."""
        out: dict[str, np.ndarray] = {}
        if self.features is not None:
            out["features"] = self.features
        if self.next_state is not None:
            out["next_state"] = self.next_state
        if self.sparse is not None:
            out |= {"s": self.sparse.s, "a": self.sparse.a, "next": self.sparse.next, "p": self.sparse.p}
        return out


def _int_array(raw: object, pointer: str, *, ndim: int) -> tuple[np.ndarray | None, list[Issue]]:
    """Coerce to an int32 array of ``ndim`` dimensions, or say why not."""
    try:
        arr = np.asarray(raw)
    except (ValueError, TypeError):
        return None, [Issue(pointer, "is not a rectangular array")]
    if arr.dtype == object:
        return None, [Issue(pointer, "is not a rectangular array of integers")]
    if arr.ndim != ndim:
        return None, [Issue(pointer, f"must have {ndim} dimension(s), got shape {arr.shape}")]
    if arr.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(arr.ravel()) | (arr.ravel() != np.round(arr.ravel())))
        if bad.size:
            idx = np.unravel_index(bad[0], arr.shape)
            return None, [Issue(_at(pointer, idx), f"must be an integer, got {arr[idx]}")]
    elif arr.dtype.kind not in "iub":
        return None, [Issue(pointer, f"must hold integers, got {arr.dtype}")]
    if arr.size and (arr.max() > np.iinfo(np.int32).max or arr.min() < np.iinfo(np.int32).min):
        return None, [Issue(pointer, "holds integers outside the int32 range")]
    return arr.astype(np.int32), []


def _float_array(raw: object, pointer: str, *, ndim: int) -> tuple[np.ndarray | None, list[Issue]]:
    """Coerce to a finite float32 array of ``ndim`` dimensions, or say why not."""
    try:
        with np.errstate(over="ignore"):  # a number past float32's range becomes inf: refused below
            arr = np.asarray(raw, dtype=np.float32)
    except (ValueError, TypeError):
        return None, [Issue(pointer, f"must be a rectangular {ndim}-D array of numbers")]
    if arr.ndim != ndim:
        return None, [Issue(pointer, f"must have {ndim} dimension(s), got shape {arr.shape}")]
    bad = np.flatnonzero(~np.isfinite(arr.ravel()))
    if bad.size:
        idx = np.unravel_index(bad[0], arr.shape)
        return None, [
            Issue(
                _at(pointer, idx), f"must be a finite number within float32's range (|x| ≤ {FLOAT32_MAX:.4g})"
            )
        ]
    return arr, []


def _at(pointer: str, index: tuple[np.intp, ...] | tuple[int, ...]) -> str:
    """Append an array index to a JSON pointer: ``/features`` + (3, 1) → ``/features/3/1``."""
    return pointer + "".join(f"/{int(i)}" for i in index)


def _deterministic_issues(ns: np.ndarray, n_states: int, n_actions: int) -> list[Issue]:
    """Shape and range of a next-state table."""
    pointer = "/transitions/next_state"
    if ns.shape != (n_states, n_actions):
        return [
            Issue(
                pointer, f"must have shape (n_states, n_actions) = ({n_states}, {n_actions}), got {ns.shape}"
            )
        ]
    bad = np.argwhere((ns < 0) | (ns >= n_states))
    return [
        Issue(_at(pointer, tuple(i)), f"next state {ns[tuple(i)]} is outside 0..{n_states - 1}")
        for i in bad[:MAX_ISSUES]
    ]


def _sparse_issues(t: SparseTransitions, n_states: int, n_actions: int) -> list[Issue]:
    """Ranges, probabilities and per-(s, a) sums of sparse transitions."""
    issues: list[Issue] = []
    for name, arr, hi in (("s", t.s, n_states), ("a", t.a, n_actions), ("next", t.next, n_states)):
        for k in np.flatnonzero((arr < 0) | (arr >= hi))[:MAX_ISSUES]:
            issues.append(Issue(f"/transitions/{name}/{k}", f"{arr[k]} is outside 0..{hi - 1}"))
    for k in np.flatnonzero((t.p < 0) | (t.p > 1))[:MAX_ISSUES]:
        issues.append(Issue(f"/transitions/p/{k}", f"probability {t.p[k]} is outside [0, 1]"))
    if issues:
        return issues
    sums = np.bincount(t.s.astype(np.int64) * n_actions + t.a, weights=t.p, minlength=n_states * n_actions)
    for sa in np.flatnonzero(np.abs(sums - 1.0) > 1e-4)[:MAX_ISSUES]:
        st, ac = divmod(int(sa), n_actions)
        issues.append(
            Issue(
                "/transitions/p",
                f"probabilities of state {st}, action {ac} sum to {sums[sa]:.6g}, not 1"
                + (" (no transitions given)" if sums[sa] == 0 else ""),
            )
        )
    return issues
