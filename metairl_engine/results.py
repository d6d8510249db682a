"""What a fit takes and gives back: `TaskData` in, `Progress` every step, `FitResult` at the end.

Plain dataclasses over numpy arrays (no torch), importable from `metairl_engine.fit` as well.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from metairl_engine.config import FitConfig
from metairl_engine.demos import Trajectory
from metairl_engine.errors import InvalidInput, Issue
from metairl_engine.mdp import MDP


@dataclass(frozen=True)
class TaskData:
    """One task: its MDP and the demonstrator's trajectories on it."""

    mdp: MDP
    trajectories: Sequence[Trajectory]
    name: str = ""


@dataclass(frozen=True)
class Progress:
    """The state of a fit after one optimisation step (losses are per task, averaged over tasks)."""

    step: int
    max_steps: int
    loss: float
    irl_loss: float
    sharing_loss: float
    heldout_nll: float | None
    elapsed_s: float


SAVE_FORMAT = 1
"""Version of the file `FitResult.save` writes (in its meta): a file of another version is refused, not misread.
One without a version is read as this one, config check included: no release wrote such a file, only builds
from before the version was stored, so one whose config lacks a setting added since is refused naming it, and
one whose config is complete is read as it was saved."""


def stored_config(data: object) -> FitConfig:
    """The `FitConfig` a saved file holds, refused at ``/file`` unless it names every setting and no other: a
    missing one would otherwise take today's default, misreading a fit made under another."""
    if not isinstance(data, dict):
        raise TypeError(f"its config is {type(data).__name__}, not an object")
    known = {f.name for f in fields(FitConfig)}
    missing, unknown = sorted(known - data.keys()), sorted(data.keys() - known)
    problems = [f"lacks the setting {name!r}" for name in missing]
    problems += [f"has the setting {name!r}, unknown to this metairl" for name in unknown]
    if problems:
        issues = [Issue("/file", f"was saved with a config that {p}") for p in problems]
        raise InvalidInput(issues)
    try:
        return FitConfig.from_dict(data)
    except InvalidInput as exc:  # a value this metairl refuses: the file is at fault, not the caller's config
        raise InvalidInput(
            [Issue("/file", f"was saved with a config whose {i.pointer} {i.message}") for i in exc.issues]
        ) from None


@dataclass(frozen=True, eq=False)
class FitResult:
    """Learned rewards of T tasks on S states with A actions, all float32.

    ``baseline`` (S,), ``rewards`` (T, S), ``values`` (T, S), ``policies`` (T, S, A) = softmax(b·Q);
    ``history`` has one `Progress` per step; ``best_step`` is the step whose parameters were kept (the
    parameters that step evaluated, before its update). ``baseline`` is the baseline network's reward, or
    the mean of the task rewards where no baseline is learned (``sharing="none"``, ``method="maxent"``).
    ``baseline_spread`` (S,) and ``reward_spread`` (T, S): per state, the standard deviation of the reward
    across the ensemble's members, each put on the members' mean scale first (`fit.member_spread`): how much
    fits from other initial weights and other held-out folds disagree there. It is a variability, not an
    error bar: it ranks where a refit of another seed moves the reward, weakly, and not where the reward is
    wrong, since every fit makes nearly the same error (`benchmarks/uncertainty.py`, docs/method.md
    "Uncertainty per state"). None where one member was fitted (``ensemble`` 1, ``maxent``).
    ``shrinkage`` and ``sparsity`` are the λ and q of ``rewards`` = baseline + λ·S_q(task reward − baseline)
    chosen by held-out likelihood, S_q zeroing the smallest share q of each task's deviations from the
    baseline (`FitConfig.shrink_deviations`, `shrinkage.sparse_deviation`; 1 and 0: the task rewards as
    learned). ``config`` is the config as fitted: what it left to the fit is stated as the fit chose it
    (``ensemble`` 0 as the members fitted, ``task_features`` auto, ``tabular_choice``'s ``method``), so a
    refit with it gives the same result.
    """

    baseline: np.ndarray
    rewards: np.ndarray
    values: np.ndarray
    policies: np.ndarray
    history: list[Progress]
    best_step: int
    config: FitConfig
    baseline_spread: np.ndarray | None = None
    reward_spread: np.ndarray | None = None
    shrinkage: float = 1.0
    sparsity: float = 0.0

    ARRAYS = ("baseline", "rewards", "values", "policies", "baseline_spread", "reward_spread")
    """The fields saved as arrays (the rest, config, history and best step, as JSON beside them)."""

    def __repr__(self) -> str:
        """One line a notebook can show: the shapes, the steps and what was kept, not every array in full."""
        tasks, states = self.rewards.shape
        spread = "" if self.reward_spread is None else ", with spreads"
        return (
            f"FitResult({tasks} tasks × {states} states × {self.policies.shape[-1]} actions{spread}; "
            f"{len(self.history)} steps, best {self.best_step}; method={self.config.method!r}, "
            f"shrinkage={self.shrinkage:g}, sparsity={self.sparsity:g})"
        )

    def save(self, path: str | Path) -> None:
        """Write this result to one ``.npz`` file (arrays as they are; config, history and best step as JSON)."""
        arrays = {name: getattr(self, name) for name in self.ARRAYS if getattr(self, name) is not None}
        meta = {
            "format": SAVE_FORMAT,
            "config": self.config.to_dict(),
            "best_step": self.best_step,
            "shrinkage": self.shrinkage,
            "sparsity": self.sparsity,
            "history": [asdict(p) for p in self.history],
        }
        with open(path, "wb") as file:
            np.savez_compressed(file, **arrays, meta=np.array(json.dumps(meta)))

    @classmethod
    def load(cls, path: str | Path) -> FitResult:
        """A result written by `save` (no pickles are read); `FileNotFoundError` where no file is, and
        `InvalidInput` at ``/file`` for any other file —
        truncated, corrupted, not one of ours — or one whose arrays do not fit together, saved in another format,
        or whose config lacks a setting or has one this metairl does not know (`stored_config`)."""
        not_ours = "is not a result written by FitResult.save"
        if not Path(path).is_file():
            raise FileNotFoundError(f"no file at {path}")
        if not zipfile.is_zipfile(
            path
        ):  # np.load would read it as a pickle and suggest loading that unsafely
            raise InvalidInput([Issue("/file", f"{not_ours} (not an .npz archive)")])
        try:
            with np.load(path, allow_pickle=False) as stored:
                meta = json.loads(str(stored["meta"]))
                arrays = {name: stored[name] for name in cls.ARRAYS if name in stored}
            if isinstance(meta, dict) and meta.get("format", SAVE_FORMAT) != SAVE_FORMAT:
                raise InvalidInput(
                    [
                        Issue(
                            "/file",
                            f"was saved in format {meta['format']!r}; this metairl reads {SAVE_FORMAT}",
                        )
                    ]
                )
            result = cls(
                baseline=arrays["baseline"],
                rewards=arrays["rewards"],
                values=arrays["values"],
                policies=arrays["policies"],
                baseline_spread=arrays.get("baseline_spread"),
                reward_spread=arrays.get("reward_spread"),
                history=[Progress(**p) for p in meta["history"]],
                best_step=meta["best_step"],
                shrinkage=meta.get("shrinkage", 1.0),
                sparsity=meta.get("sparsity", 0.0),
                config=stored_config(meta["config"]),
            )
        except InvalidInput:
            raise
        except (
            OSError,
            EOFError,
            ValueError,
            KeyError,
            TypeError,
            AttributeError,
            zipfile.BadZipFile,
            zlib.error,
        ) as exc:
            reason = f"{type(exc).__name__}: {exc}".split("\n")[0][:200]
            raise InvalidInput([Issue("/file", f"{not_ours} ({reason})")]) from None
        n_tasks, n_states = result.rewards.shape if result.rewards.ndim == 2 else (0, -1)
        if (
            result.baseline.shape != (n_states,)
            or result.values.shape != (n_tasks, n_states)
            or (result.policies.ndim != 3 or result.policies.shape[:2] != (n_tasks, n_states))
        ):
            shapes = ", ".join(
                f"{n} {getattr(result, n).shape}" for n in ("baseline", "rewards", "values", "policies")
            )
            raise InvalidInput([Issue("/file", f"holds arrays that do not fit together: {shapes}")])
        return result
