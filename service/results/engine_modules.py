"""The engine's scipy modules the results use, each imported on first use: an API process that only serves jobs and
downloads never loads scipy (~70 MB)."""

from __future__ import annotations

from types import ModuleType
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    pass


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
