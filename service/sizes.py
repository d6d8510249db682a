"""Size limits (settings ``METAIRL_MAX_*``): how large an MDP, an uploaded array or a network may be.

Checked when an MDP is uploaded and again when a job is submitted (the limits may have been lowered since),
each failure a 422 naming the setting, so no request and no job can ask for unbounded memory.
"""

from __future__ import annotations

from collections.abc import Sequence

from metairl_engine.errors import Issue
from service.problems import Unprocessable
from service.settings import Settings


def too_large(pointer: str, message: str) -> Unprocessable:
    """A 422 at `pointer` saying what is too large and which setting bounds it."""
    where = f" at {pointer}" if pointer else ""
    return Unprocessable(f"Too large{where}: {message}.", errors=[{"pointer": pointer, "message": message}])


def check_array_elements(name: str, shape: Sequence[int], settings: Settings, *, pointer: str) -> None:
    """422 if an uploaded array of `shape` has more than `max_array_elements` elements."""
    n = 1
    for d in shape:
        n *= int(d)
    if n > settings.max_array_elements:
        raise too_large(
            pointer,
            f"array {name!r} of shape {tuple(int(d) for d in shape)} has {n:,} elements; at most "
            f"{settings.max_array_elements:,} (METAIRL_MAX_ARRAY_ELEMENTS)",
        )


def mdp_size_issues(
    n_states: int,
    n_actions: int,
    n_features: int | None,
    settings: Settings,
    *,
    pointer: str,
    what: str = "the MDP",
) -> list[Issue]:
    """An issue at `pointer` if states × actions exceeds `max_state_actions`, another if the features are wider
    than `max_features`."""
    issues = []
    if n_states * n_actions > settings.max_state_actions:
        issues.append(
            Issue(
                pointer,
                f"{what} has {n_states:,} states × {n_actions:,} actions = {n_states * n_actions:,}; at most "
                f"{settings.max_state_actions:,} (METAIRL_MAX_STATE_ACTIONS)",
            )
        )
    if n_features is not None and n_features > settings.max_features:
        issues.append(
            Issue(
                pointer,
                f"{what} has {n_features:,} features per state; at most {settings.max_features:,} "
                "(METAIRL_MAX_FEATURES)",
            )
        )
    return issues


def hidden_issues(hidden: Sequence[int], settings: Settings) -> list[Issue]:
    """An issue at /config/hidden/<i> per hidden layer wider than `max_hidden_units`."""
    return [
        Issue(
            f"/config/hidden/{i}",
            f"asks for {units:,} hidden units; at most {settings.max_hidden_units:,} (METAIRL_MAX_HIDDEN_UNITS)",
        )
        for i, units in enumerate(hidden)
        if units > settings.max_hidden_units
    ]


def request_memory_issues(what: str, nbytes: float, settings: Settings, *, pointer: str) -> list[Issue]:
    """An issue at `pointer` if building `what` would take `nbytes` of memory, more than
    ``api_max_request_memory_mb``; asked before the allocation, with an estimate from declared shapes, row
    counts or body size."""
    budget = settings.api_max_request_memory_mb * 2**20
    if nbytes <= budget:
        return []
    return [
        Issue(
            pointer,
            f"{what} would take about {nbytes / 2**20:,.0f} MiB of memory; at most "
            f"{settings.api_max_request_memory_mb:,} MiB per request (METAIRL_API_MAX_REQUEST_MEMORY_MB)",
        )
    ]


def first_too_large(issues: list[Issue]) -> None:
    """`too_large` naming the first of ``issues`` (a `*_issues` check's answer), if any: an upload read in
    stages stops at the first limit it passes."""
    if issues:
        raise too_large(issues[0].pointer, issues[0].message)


GRID_BYTES_PER_TRANSITION = 40
"""Peak memory per (state, action) while a deterministic grid is built and validated (measured: 32M
state-actions took 1.2 GB), and per stored transition of a slippery one (`grid_issues`)."""
GRID_BYTES_PER_STATE = 128
"""Peak memory per state of a grid's coordinate features and layout."""


def grid_issues(
    *,
    width: int,
    height: int,
    moves: int,
    stay: bool,
    slip: float,
    velocity: bool,
    settings: Settings,
    pointer: str = "",
) -> list[Issue]:
    """Problems of a grid to be built: its states × actions over `max_state_actions`, else building it taking
    more than the per-request memory budget (a slippery grid stores up to one transition per action pair).
    Each points at the grid's larger side under `pointer` (the grid object's own pointer)."""
    n_states = width * height * (8 if velocity else 1)
    n_actions = 8 if velocity else moves + (1 if stay else 0)
    side = f"{pointer}/{'width' if width >= height else 'height'}"
    what = f"the {width:,}×{height:,} grid"
    issues = mdp_size_issues(n_states, n_actions, None, settings, pointer=side, what=what)
    if issues:
        return issues
    transitions = n_states * n_actions * (n_actions if slip > 0 else 1)
    estimate = transitions * GRID_BYTES_PER_TRANSITION + n_states * GRID_BYTES_PER_STATE
    return request_memory_issues(f"building {what}", estimate, settings, pointer=side)
