"""metairl_engine: meta inverse reinforcement learning via maximum reward sharing (Li & Burdick).

A plain library (numpy + torch, no web, no database), usable from a notebook (docs/notebook.md):
``from metairl_engine import fit, grid_mdp, TaskData, Trajectory``. Importing the package imports neither
torch nor the fit: the numpy-only modules (`mdp`, `demos`, `config`, `errors`, `grids`, `metrics`) are what
the API process uses. ``from metairl_engine import fit`` (or ``metairl_engine.fit``) imports the module `metairl_engine.fit` (and
torch), which is callable as its function `fit`.
"""

import importlib

from metairl_engine.config import FitConfig
from metairl_engine.demos import Trajectory, validate_trajectories
from metairl_engine.errors import Cancelled, Diverged, EngineError, InvalidInput, Issue
from metairl_engine.grids import grid_mdp
from metairl_engine.mdp import MDP, Layout, SparseTransitions
from metairl_engine.results import FitResult, Progress, TaskData

__all__ = [
    "MDP",
    "Cancelled",
    "Diverged",
    "EngineError",
    "FitConfig",
    "FitResult",
    "InvalidInput",
    "Issue",
    "Layout",
    "Progress",
    "SparseTransitions",
    "TaskData",
    "Trajectory",
    "fit",
    "grid_mdp",
    "validate_trajectories",
]


def __getattr__(name: str) -> object:
    """``metairl_engine.fit`` after a plain ``import metairl_engine``: the module `metairl_engine.fit`
    (callable as its function), imported with torch on first use."""
    if name == "fit":
        return importlib.import_module("metairl_engine.fit")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
