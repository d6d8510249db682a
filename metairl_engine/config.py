"""`FitConfig`: every knob of a fit in one frozen dataclass, stored with each job's results.

numpy-free and torch-free so the API can validate a job's config (docs/api.md, "Jobs": the contract names) without
loading the engine. Field docstrings are the reference documentation of each setting.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
from typing import Any, Literal, get_args, get_origin, get_type_hints

from metairl_engine.errors import InvalidInput, Issue, check
from metairl_engine.mdp import python_number

Method = Literal["meta_irl", "maxent", "shared_maxent"]
Sharing = Literal["none", "l2", "huber", "std", "entropy"]
SharingStates = Literal["all", "visited"]
Backup = Literal["max", "logsumexp", "bgi"]
TabularInputs = Literal["coordinates", "one_hot"]
TaskFeatures = Literal["auto", "yes", "no"]

MAX_SEED = 2**63 - 1
"""The largest seed (torch and numpy take 64-bit seeds)."""

BOUNDS: dict[str, tuple[Callable[[Any, Any], bool], str]] = {
    "ge": (operator.ge, "≥"),
    "gt": (operator.gt, ">"),
    "le": (operator.le, "≤"),
    "lt": (operator.lt, "<"),
}
"""The comparisons a numeric setting's bounds may use (pydantic's names), and how a message writes them."""


def bounds(**limits: float) -> dict[str, float]:
    """A field's ``metadata``: its allowed range as ``ge``/``gt``/``le``/``lt`` limits, checked by `FitConfig`
    and published as the setting's range in the API's schema."""
    assert set(limits) <= set(BOUNDS), limits
    return limits


def type_problem(value: Any, hint: Any) -> str | None:
    """Why ``value`` is not of a setting's type ``hint`` (a Literal, bool, int, float, or a tuple of ints,
    maybe None), or None when it is: a notebook's ``FitConfig(method="MAXENT")`` must not run another method."""
    options = get_args(hint)
    if get_origin(hint) is Literal:
        return None if value in options else "must be one of " + ", ".join(repr(o) for o in options)
    if type(None) in options:
        if value is None:
            return None
        hint = next(o for o in options if o is not type(None))
    if hint is bool:
        return None if isinstance(value, bool) else "must be true or false"
    if hint is int:
        return None if type(value) is int else "must be an integer"
    if hint is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        return None if ok else "must be a finite number"
    if get_origin(hint) is tuple:
        ok = isinstance(value, tuple | list) and all(type(v) is int for v in value)
        return None if ok else "must be a list of integers"
    return None


def out_of_bounds(value: float, limits: Mapping[str, float]) -> str | None:
    """A ``must be ≥ 0 and < 1`` message when ``value`` breaks ``limits``; None when it is within them."""
    if all(BOUNDS[k][0](value, limit) for k, limit in limits.items()):
        return None
    return "must be " + " and ".join(f"{BOUNDS[k][1]} {limit}" for k, limit in limits.items())


@dataclass(frozen=True, kw_only=True)
class FitConfig:
    """How to learn rewards from one demonstrator's tasks (defaults are the recommended settings).

    Whatever the settings, the networks see only the MDP's feature columns that vary over the states: a
    constant column carries nothing, and in the first layer acts as a copy of the bias that Adam steps on its
    own (`fit.varying_columns`, docs/method.md "Constant feature columns")."""

    method: Method = "meta_irl"
    """``meta_irl``: the paper's VR-function method with reward sharing; ``maxent``: tabular
    maximum-causal-entropy IRL by soft value iteration (reference solver, one task at a time);
    ``shared_maxent``: the same solver with the rewards shared, every task's reward one shared reward (the
    baseline) except at the final states of its demonstrations that ended by choice (`maxent.py`)."""

    sharing: Sharing = "huber"
    """Reward-sharing loss between each task reward r_i and the baseline r_b (paper §III-C). With ``none``
    no baseline network is learned and the result's baseline is the mean of the task rewards, a summary
    rather than an estimate of the inherent reward."""

    sharing_weight: float = field(default=1.0, metadata=bounds(ge=0))
    """Weight of the sharing loss relative to the IRL loss; both are per-task means (NLL per demonstrated
    step, sharing loss per compared state), so the weight does not depend on the numbers of states or steps."""

    sharing_states: SharingStates = "all"
    """Evaluate the sharing loss on all states or only on states visited by the task's demonstrations."""

    sharing_blocks: int = field(default=0, metadata=bounds(ge=0, le=1024))
    """With ``sharing_states="all"``: the states are split at random into this many fixed blocks and each
    step compares r_i with r_b on one block, in turn, so every state is compared once every this many steps.
    The per-state mean over a block is an unbiased estimate of the mean over all states at a fraction of the
    cost; the rewards returned are still evaluated on every state. 0 (default): automatic
    (`sharing_block_count`: one block below 32,768 states, blocks of about 8,192 states above); 1: every
    state every step."""

    baseline_features: tuple[int, ...] | None = None
    """Columns of the MDP's state features that the baseline network r_b sees; None: all of them, like the VR
    networks. On a velocity grid (features x, y, direction one-hot) ``(0, 1)`` makes r_b a function of the
    cell alone, compared by the sharing loss with each task reward in every direction of motion at that cell:
    see docs/motion.md (identifiability) for why motion fits want it. Needs state features, or the coordinates
    an MDP without them gets (``tabular_inputs="coordinates"``: x, y, then the channel one-hot of a layout)."""

    baseline_elsewhere_weight: float = field(default=0.1, metadata=bounds(ge=0, le=1))
    """How much the baseline network learns from a task's reward on the states where that task's training steps
    give no evidence (neither visited nor one move from a visit: `evidence.py`), relative to the states they
    visit. Off its evidence a task reward is what its network extrapolates; below 1 the baseline follows the
    tasks that saw a state more than those that did not, while every task is still pulled toward the baseline
    on every state. One move from a visit the baseline learns at ½ (or this weight, if larger): the reward
    there rests on values the demonstrated choices compare only in part. A state exactly one task visited
    counts every task at 1: a single witness cannot tell the shared reward from its own goal. 1: every state
    alike, as the paper has it; 0.1 (default): with eight tasks, a state one of two witnesses visited outweighs
    the six extrapolations there (docs/method.md, "Where the baseline learns from")."""

    task_coordinates: bool = True
    """The task (VR) networks also see each state's coordinates (`coordinates.state_coordinates`: from the
    layout, else recovered from the transition graph) and their sinusoids at 2 octaves besides the MDP's
    state features, unless the features already hold them; the baseline network sees the features alone. A task's own reward — a goal — is a
    place, which features describing the world (distances to objects, colours around a cell) cannot single
    out: without the place a task network spreads its goal over every state whose features look alike.
    Features that are the coordinates (a grid's x, y) are left as they are."""

    task_features: TaskFeatures = "yes"
    """With `task_coordinates`: whether the task networks see the MDP's state features beside the place
    (``yes``) or the place alone (``no``: the coordinates and their sinusoids; the baseline network sees the
    features either way). ``auto``: fit both and keep the place alone only where its held-out NLL beats the
    other's by more than one standard error (`fit._fit_choosing_task_inputs`). With the features a task
    network can repeat the world's structure around its goal, and the baseline, pulled toward every task,
    takes in the goals' feature signature; with the place alone the world's structure is the baseline's
    alone, and a task cannot correct what the baseline got wrong along the features. Which is better depends
    on the world (docs/method.md, "Task inputs"). ``auto`` costs a second fit, and only where the choice
    exists: with sharing, several tasks, and features that are not the coordinates themselves."""

    shrink_deviations: bool = True
    """Each task reward returned is r_b + λ·S_q(r_i − r_b): the baseline plus λ of the task's learned
    deviation from it, made sparse by S_q, which zeroes the smallest share q of the states' deviations (a soft
    threshold; what a task adds to the shared reward — a goal, an obstacle — is mostly local). λ ∈ {0, ¼, ½,
    ¾, 1} and q ∈ {0, ½, 0.9, 0.95, 0.99, 0.995}: of the candidates whose optimal policies predict the
    held-out steps within one standard error of the best (the ensemble's K-fold held-out NLL), the one whose
    rewards depart least from the baseline, Σ|λ·S_q(r_i − r_b)|: the most sharing the held-out steps allow.
    With a few demonstrations much of a deviation is noise the held-out steps do not bear out.
    Costs one value iteration per candidate on every state after the fit, so only up to `shrinkage.BUDGET`
    (2^17) task-states T·K·S: an 80,000-state fit keeps λ = 1, q = 0. Only with sharing (a baseline to
    shrink towards) and a hold-out; the choice is `FitResult.shrinkage` and `FitResult.sparsity`. False:
    the task networks' rewards as learned."""

    stay_at_ends: bool = True
    """A demonstration that ended by choice (where its task's demonstrations differ in length: shorter than the
    longest, or ending where another ends; `demos.ended_by_choice`) counts one more step, the MDP's stay action at its
    final state (`planning.stay_actions`; none there: nothing added). The likelihood of the demonstrated
    actions alone discards where a demonstration stops, the plainest evidence of its goal: a task reward
    could then peak beside the goal, which at γ 0.99 costs the task's policy its goal (docs/method.md,
    "Where a demonstration stops"). Demonstrations cut at one length (a step limit, a recording's end) are
    left as they are. The ``maxent`` method counts the final state's visit already. False: the steps as
    given."""

    tabular_inputs: TabularInputs = "coordinates"
    """What the networks see of each state when the MDP has no state features. ``coordinates``: the state's
    position, from the MDP's layout when it has one (x, y in [0, 1], plus a one-hot of its channel), else
    recovered from the transition graph (`coordinates.graph_coordinates`), so rewards carry over to
    neighbouring states as they do with (x, y) features. ``one_hot``: a learned embedding per state (the
    paper's tabular network), where a state no demonstration reaches gets its reward from the sharing loss
    alone."""

    tabular_choice: bool = True
    """With an MDP without state features (or, without a layout, with features that only say where a state
    is: `coordinates.features_are_positions`), sharing and a hold-out: whether the data may choose the tabular
    solver with shared rewards (``shared_maxent``) over the networks. Coordinates assume the reward is smooth
    in the place, as a terrain's cost is; a reward of small patches (objectworld's) it is not, and there the
    networks extrapolate a wrong trend over every state no demonstration reaches, while the solver leaves
    them at 0. Each task's demonstrations are split into up to three folds, each held out once
    (`holdout.demonstration_folds`), and in each the networks and the solver each task alone (``maxent``,
    which extrapolates nothing) are fitted on the rest; where the solver's policies give the held-out
    demonstrations the higher likelihood (each with its stay where it ended by choice, as `stay_at_ends` has
    the fits count it; `holdout.predicts_better`: neither extrapolation is the default),
    ``shared_maxent`` is fitted on every demonstration, else the networks are refitted. The choice is the
    result's ``config`` (``method``, or this set to False), so refitting with it gives the same result. Costs
    up to six extra fits on such MDPs (three of them the quick solver's), none elsewhere (docs/method.md, "MDPs
    without features")."""

    backup: Backup = "max"
    """Bellman backup V(s) from Q(s, ·): max (paper eq. 7), logsumexp (MaxEnt) or BGI's (1/k)·logsumexp(k·Q)."""

    bgi_k: float = field(default=10.0, metadata=bounds(gt=0))
    """Sharpness k of the BGI backup (only with ``backup="bgi"``)."""

    confidence: float = field(default=1.0, metadata=bounds(gt=0))
    """The paper's b: demonstrated actions follow softmax(b·Q(s, ·)) (paper eq. 9–10)."""

    hidden: tuple[int, ...] = (100, 50, 25)
    """Hidden layer widths of each VR network and of the baseline network; empty: none, each network affine
    in its inputs (the linear reward of classic feature-based IRL)."""

    fourier_octaves: int = field(default=0, metadata=bounds(ge=0, le=8))
    """Input encoding: each state feature x also enters the networks as sin(2^l·π·x), cos(2^l·π·x) for
    l < this many octaves (0: raw features; no effect on tabular MDPs). Lets the MLPs represent hills."""

    learning_rate: float = field(default=0.01, metadata=bounds(gt=0, le=1))
    """Adam's learning rate (paper: 0.01)."""

    max_steps: int = field(default=1000, metadata=bounds(ge=1, le=100_000))
    """Upper bound on optimisation steps (the held-out rule usually stops earlier without sharing). ``maxent``
    solves each task alone, up to this many L-BFGS iterations per task: its progress counts every task's, out
    of ``max_steps`` × tasks."""

    tolerance: float = field(default=1e-6, metadata=bounds(ge=0))
    """Stop when the relative change of the training loss per step stays below this for 10 steps in a row."""

    holdout_fraction: float = field(default=0.2, metadata=bounds(ge=0, lt=1))
    """Fraction of each task's demonstrated steps held out to choose the stopping step by held-out
    likelihood, never by the true reward: the kept parameters are those of the last step whose held-out
    NLL is within one standard error of the best (see fit.HeldOutStopper). 0 disables the hold-out; the
    fit then runs on all steps to ``max_steps`` or ``tolerance``. A demonstrator that always repeats its action
    where it returns has its repeated steps counted once, training and held-out alike
    (`holdout.repeats_its_decisions`)."""

    patience: int = field(default=200, metadata=bounds(ge=0))
    """Stop once the held-out NLL has made no meaningful progress (a new best by more than one standard error
    of the last) for this many steps (only with a hold-out; 0: never; `fit.HeldOutStopper`)."""

    ensemble: int = field(default=0, metadata=bounds(ge=0, le=16))
    """Members K of the ensemble: each reward is the mean of K fits run side by side as one batch of T·K
    networks, member k with its own initial weights, holding out fold k of each task's steps (so together
    they learn from every step); the step kept is the one their held-out folds together choose (a K-fold
    cross-validated NLL, fit.HeldOutStopper). Averaging K fits cuts
    the variance of a reward learned from a few demonstrations; a step costs about K times as much.
    0 (default): K = 4 for small fits, fewer as tasks × states grow, 1 from 32,768 (`ensemble_size`); the
    result's ``config`` states the K fitted."""

    seed: int = field(default=0, metadata=bounds(ge=0, le=MAX_SEED))
    """Seed of every random choice (initial weights, hold-out split): same seed, same result."""

    def __post_init__(self) -> None:
        issues: list[Issue] = []

        def need(ok: bool, name: str, message: str) -> None:
            if not ok:
                issues.append(Issue(f"/config/{name}", message))

        hints = get_type_hints(FitConfig)
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(
                value, list | tuple
            ):  # a list where a tuple is meant: the same setting, kept hashable
                object.__setattr__(self, f.name, value := tuple(python_number(v) for v in value))
            elif python_number(value) is not value:  # np.int64(200): the Python number it holds
                object.__setattr__(self, f.name, value := python_number(value))
            problem = type_problem(value, hints[f.name])
            if problem is None and f.metadata:
                problem = out_of_bounds(value, f.metadata)
            if problem:
                issues.append(Issue(f"/config/{f.name}", problem))
        if issues:  # the checks below assume every setting has its type
            check(issues)
        need(
            self.baseline_features is None
            or (
                len(self.baseline_features) > 0
                and all(isinstance(c, int) and c >= 0 for c in self.baseline_features)
                and len(set(self.baseline_features)) == len(self.baseline_features)
            ),
            "baseline_features",
            "must be null or distinct feature column indices ≥ 0",
        )
        need(all(isinstance(h, int) and h > 0 for h in self.hidden), "hidden", "must be positive integers")
        need(len(self.hidden) <= 8, "hidden", "at most 8 hidden layers")
        check(issues)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (stored with every job and reward)."""
        d = asdict(self)
        d["hidden"] = list(self.hidden)
        if self.baseline_features is not None:
            d["baseline_features"] = list(self.baseline_features)
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FitConfig:
        """Build from JSON, rejecting unknown keys with a pointer to them."""
        known = {f.name for f in fields(cls)}
        unknown = [k for k in data if k not in known]
        if unknown:
            raise InvalidInput([Issue(f"/config/{k}", "is not a known setting") for k in unknown])
        kwargs = dict(data)
        for name in ("hidden", "baseline_features"):
            if isinstance(kwargs.get(name), list):
                kwargs[name] = tuple(kwargs[name])
        return cls(**kwargs)


def baseline_column_issues(config: FitConfig, *, n_columns: int | None) -> list[Issue]:
    """Why ``baseline_features`` names columns the baseline cannot see when the networks' inputs have
    ``n_columns`` columns (None: the paper's one-hot inputs, no columns); checked at submission and by the fit."""
    if config.baseline_features is None or (
        n_columns is not None and max(config.baseline_features) < n_columns
    ):
        return []
    what = (
        "the networks see a one-hot of each state"
        if n_columns is None
        else f"they see {n_columns} feature columns"
    )
    return [Issue("/config/baseline_features", f"names columns the baseline cannot see: {what}")]


ENSEMBLE_BUDGET = 2**15
"""Task-states per member that the automatic ensemble may fill (``FitConfig.ensemble = 0``)."""

MAX_AUTO_MEMBERS = 4
"""The most members the automatic ensemble uses."""


def chooses_tabular_method(config: FitConfig, *, has_features: bool) -> bool:
    """Whether a fit may run both the networks and the tabular solver (`FitConfig.tabular_choice`): the
    networks' method, sharing and a hold-out, on an MDP without features (`fit.tabular_choice_applies` adds
    the demonstrations it needs and counts features that only say where a state is as none)."""
    return (
        config.tabular_choice
        and config.method == "meta_irl"
        and not has_features
        and config.sharing != "none"
        and config.holdout_fraction > 0
    )


def ensemble_size(config: FitConfig, *, n_tasks: int, n_states: int) -> int:
    """Members K: ``config.ensemble``, or with 0 as many as fit ENSEMBLE_BUDGET (1 … MAX_AUTO_MEMBERS).

    A step costs about K times a member's; a fit of T tasks on S states already evaluates T·S task-states
    per step, so K = ⌊2^15 / (T·S)⌋ keeps small fits (where a few demonstrations leave the most variance)
    averaged over 4 members and leaves large ones (an 80,000-state velocity grid) single.
    """
    if config.ensemble:
        return config.ensemble
    return max(1, min(MAX_AUTO_MEMBERS, ENSEMBLE_BUDGET // (n_tasks * n_states)))


BLOCK_STATES = 2**13
"""About this many states per sharing block when the blocks are automatic (``FitConfig.sharing_blocks = 0``)."""

MIN_BLOCKS = 4
"""The fewest automatic blocks worth having: with fewer, a block's successors cover most of the states and a
step costs nearly as much as one on all of them."""


def sharing_block_count(config: FitConfig, *, n_states: int) -> int:
    """Blocks of the all-states sharing loss: ``config.sharing_blocks``, or with 0 about one per
    BLOCK_STATES states once there are at least MIN_BLOCKS of them (else 1: every state every step)."""
    if config.sharing_blocks:
        return min(config.sharing_blocks, n_states)
    blocks = n_states // BLOCK_STATES
    return blocks if blocks >= MIN_BLOCKS else 1
