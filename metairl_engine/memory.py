"""How much memory a fit needs, estimated from the problem's sizes before any of it is allocated.

Pure arithmetic (no numpy, no torch), so a worker can refuse a job that cannot fit in its memory before
loading its inputs, instead of being killed by the kernel part-way and re-running the job to the same end.
The chunk sizes that bound the fit's per-state tensors live here too, since the estimate depends on them.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import itertools
import platform
from collections.abc import Iterator
from dataclasses import dataclass, replace

from metairl_engine.config import FitConfig, chooses_tabular_method, ensemble_size
from metairl_engine.coordinates import LANDMARKS, TASK_COORDINATE_COLUMNS

COORDINATE_COLUMNS = 10
"""Feature columns counted for an MDP without features under ``tabular_inputs="coordinates"``: x and y, and a
channel one-hot for a layout of up to 8 panels (a velocity grid's)."""

EVAL_CHUNK = 16_384
"""States per chunk when evaluating the final networks on every state (bounds memory at 80,000 states)."""

TRAIN_CHUNK = 1_024
"""Above this many states a training step runs the networks chunk by chunk (see `fit.gradient_step`)."""

FLOAT = 4
"""Bytes of a float32 (parameters, activations, Q values)."""

INDEX = 8
"""Bytes of an int64 (index tensors and arrays)."""

RUNTIME = 320 * 1024 * 1024
"""torch's and scipy's libraries and buffers in the process that runs the fit (measured: 326 MB for a
25-state fit, whose own tensors are a few kB)."""

ALLOCATOR_SLACK = 1.2
"""Peak resident memory per byte of live tensors: freed tensors the allocator keeps and cannot reuse for
later, differently sized ones. With it the estimate came to 0.87–1.14 times the measured peak of nine
meta-IRL fits of 2,000 to 90,000 states (benchmarks/memory.py)."""

PARAMETER_COPIES = 5
"""Copies of each network parameter: the weight, its gradient, Adam's two moments and the kept copy."""

TEMPERATURES = 17
"""Temperatures at which the held-out NLL is scored (`fit.TEMPERATURES`)."""


@dataclass(frozen=True)
class FitMemory:
    """The estimated peak memory of a fit, in bytes, by what it is spent on (see `fit_memory`)."""

    runtime: int
    """torch's and scipy's own memory (`RUNTIME`)."""
    inputs: int
    """The loaded MDPs and trajectories, and the features as the networks read them."""
    networks: int
    """The networks' parameters, gradients, Adam's moments and the kept copy."""
    rows: int
    """The index tensors of the rows of Q (demonstrated steps and sharing rows), held throughout."""
    training: int
    """One training step at its peak (the tabular methods: the solve)."""
    evaluation: int
    """The final evaluation on every state, and the results (the tabular methods: the results)."""

    @property
    def total(self) -> int:
        """The peak: the runtime, and the tensors held throughout plus the larger of a training step and the
        final evaluation, with the allocator's slack."""
        tensors = self.inputs + self.networks + self.rows + max(self.training, self.evaluation)
        return self.runtime + int(ALLOCATOR_SLACK * tensors)

    def advice(self) -> str:
        """What to change in the job to need less, for the part that needs the most."""
        parts = {
            "inputs": self.inputs,
            "networks": self.networks,
            "rows": self.rows + max(self.training, self.evaluation),
        }
        largest = max(parts, key=lambda name: parts[name])
        if largest == "networks":
            return (
                "most of it holds the networks and their optimiser state: use smaller config.hidden layers, "
                "a smaller config.ensemble or fewer tasks"
            )
        if largest == "inputs":
            return (
                "most of it holds the MDPs' features and their encoding: use fewer states or feature columns, "
                "or a smaller config.fourier_octaves"
            )
        return (
            "most of it holds per-state values of every task and ensemble member: use fewer states or tasks, "
            'a smaller config.ensemble, or config.sharing_states "visited"'
        )


def fit_memory(
    config: FitConfig,
    *,
    n_tasks: int,
    n_states: int,
    n_actions: int,
    n_features: int | None,
    n_steps: int,
    n_mdps: int,
    successors: float = 1.0,
) -> FitMemory:
    """Estimated peak bytes of `fit` on ``n_tasks`` tasks sharing one state space, and what they are spent on.

    ``n_features`` is the MDPs' feature columns (None: tabular), ``n_steps`` the demonstrated steps of all
    tasks, ``n_mdps`` the distinct MDPs loaded, ``successors`` the mean next states per (state, action)
    (1: deterministic). Counted, for the meta-IRL method: the loaded inputs (transitions, features, their
    copy in input units and their Fourier encoding, trajectories); the VR and baseline networks' parameters with their gradients,
    Adam's moments and the kept copy; the index tensors of the training, held-out and sharing rows (one
    per network and state with ``sharing_states="all"``), the task networks' inputs including the
    `TASK_COORDINATE_COLUMNS` of coordinates `FitConfig.task_coordinates` adds to an MDP's features (counted
    even where the features already are the coordinates and the fit adds none: a few columns too many); then the larger of one training step (the
    activations of one chunk of states forward and backward, Q and its gradient on every row, Adam's
    temporaries) and the final evaluation on every state (Q, values and policies of all networks, and the
    results). With the tabular methods (``maxent``, ``shared_maxent``): the inputs, one value iteration, each
    task's objective and the results. Each term
    counts the tensors it names at their largest (e.g. every state as needed by the networks); small
    tensors and Python objects fall under `RUNTIME`.
    """
    if chooses_tabular_method(config, has_features=False):
        # The networks and the tabular solver run one after the other: the peak is the larger one's. Counted
        # with features too: features that only say where a state is get the choice as well
        # (`fit.tabular_choice_applies`), which the sizes alone do not tell.
        estimate = functools.partial(
            fit_memory,
            n_tasks=n_tasks,
            n_states=n_states,
            n_actions=n_actions,
            n_features=n_features,
            n_steps=n_steps,
            n_mdps=n_mdps,
            successors=successors,
        )
        return max(
            estimate(replace(config, tabular_choice=False)),
            estimate(replace(config, method="shared_maxent")),
            key=lambda m: m.total,
        )
    s, a, t = n_states, n_actions, n_tasks
    deterministic = successors == 1.0
    # A next-state table (int32), or the stored (s, a, next, p) triples and their CSR matrix.
    transitions = n_mdps * (s * a * 4 if deterministic else int(s * a * successors * (16 + 12)))
    inputs = transitions + n_mdps * s * (n_features or 0) * FLOAT + n_steps * 2 * INDEX * 3
    if config.method != "meta_irl":
        nnz = int(s * a * successors)
        # CSR P of each MDP, Pᵀ and P_π; Q, policy, temporaries; L-BFGS; each task's objective (warm-started
        # value, visits, Σ P); shared_maxent optimises every state of the shared reward at once.
        solve = (n_mdps + 3) * nnz * 12 + s * a * 8 * 6 + s * 8 * 40 + t * s * 8 * 3
        results = t * s * a * 12 + 3 * t * s * FLOAT  # float64 policies per task, then their float32 copy
        return FitMemory(RUNTIME, inputs, 0, 0, solve, results)

    k = ensemble_size(config, n_tasks=t, n_states=s)
    nets = t * k
    if n_features is not None:
        # The features in input units (`fit.input_units`), a copy where a column moves or is rescaled.
        inputs += s * n_features * FLOAT
    # The task networks of an MDP with features also see its coordinates and their waves.
    task_columns = TASK_COORDINATE_COLUMNS if config.task_coordinates and n_features is not None else 0
    if n_features is None and config.tabular_inputs == "coordinates":
        # Positions recovered from the MDP (coordinates.py) stand in for features; while they are computed,
        # float64 hop distances to the landmarks, their squares and the positions.
        n_features = COORDINATE_COLUMNS
        inputs += LANDMARKS * s * 8 * 3
    tabular = n_features is None
    octave_columns = 1 + 2 * config.fourier_octaves
    width = s if tabular else ((n_features or 0) + task_columns) * octave_columns
    base_width = (
        width
        if tabular
        else (len(config.baseline_features) if config.baseline_features else n_features or 0) * octave_columns
    )
    if not tabular:
        # Encoded features and the copies the networks read (VR, baseline), plus the encoding's float64 waves.
        inputs += 2 * s * width * FLOAT + 2 * s * base_width * FLOAT + s * width * 8 * 3

    def parameters(members: int, n_inputs: int) -> int:
        """Parameters of ``members`` stacked MLPs ``n_inputs → hidden… → 1``."""
        widths = [n_inputs, *config.hidden, 1]
        return members * sum(i * o + o for i, o in itertools.pairwise(widths))

    sharing = config.sharing != "none"
    n_parameters = parameters(nets, width) + (parameters(k, base_width) if sharing else 0)
    networks = PARAMETER_COPIES * n_parameters * FLOAT

    # Rows of Q: K copies of every demonstrated step (train or held out) and the sharing rows.
    step_rows = k * n_steps
    if not sharing:
        share_rows = 0
    elif config.sharing_states == "all":
        share_rows = nets * s
    else:
        share_rows = k * min(t * s, n_steps)
    # Bytes per (row, action) of a Q index: a gather index, or P's CSR row pointer and the column index
    # and value of each successor in P and in Pᵀ; and of the temporaries while one is built.
    entry = INDEX if deterministic else INDEX + int(successors * 24)
    build = 12 if deterministic else int(successors * 60)
    rows = (step_rows + share_rows) * (a * entry + 6 * INDEX)

    first = 0 if tabular else width  # a features input is broadcast to every network
    layers = [first, *config.hidden, 1]  # through the output layer (with no hidden layer, that one alone)

    def activations(members: int, n_inputs: int) -> int:
        """Saved activations and their gradients of ``members`` networks on one chunk of states."""
        return members * min(s, TRAIN_CHUNK) * (n_inputs + 2 * sum(config.hidden)) * FLOAT

    largest_weight = max(i * o for i, o in itertools.pairwise([width, *config.hidden, 1]))
    held = int(step_rows * config.holdout_fraction)
    step = (
        activations(nets, first)
        + (activations(k, 0 if tabular else base_width) if sharing else 0)
        + 2 * (nets + k) * s * FLOAT  # f and r_b with their gradients
        # Q, its log-softmax or max and its gradient; two index-sized buffers for the gather's backward.
        + (step_rows + share_rows) * a * (3 * FLOAT + 2 * entry)
        + share_rows * 10 * FLOAT  # V, r, r − r_b, the sharing loss's terms and their gradients
        + held * (2 * TEMPERATURES * a + TEMPERATURES) * FLOAT  # the calibrated NLL: t·b·Q, its log-softmax
    )
    adam = 2 * nets * largest_weight * FLOAT  # Adam's temporaries of the largest weight, after the backward
    training = max(step, adam)
    all_rows = nets * s
    forward = nets * min(s, EVAL_CHUNK) * max(i + o for i, o in itertools.pairwise(layers)) * FLOAT
    q_all = all_rows * a * (entry + max(build, 3 * FLOAT)) + all_rows * 2 * INDEX  # Q, b·Q, softmax
    evaluation = (
        max(forward, q_all)  # first the networks, one chunk and two layers at a time; then Q on every state
        + all_rows * 4 * FLOAT  # f, V, r and their means
        + t * s * a * 2 * FLOAT  # the mean policies and their float32 copy in the result
    )
    return FitMemory(RUNTIME, inputs, networks, rows, training, evaluation)


_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters (malloc.h)
KEPT_HEAP = 1 << 30
"""Freed memory glibc may keep for reuse during a fit (`retained_heap`)."""


@contextlib.contextmanager
def retained_heap() -> Iterator[None]:
    """Let glibc keep freed memory for reuse while a fit runs, and give it back to the system at the end.

    Each step allocates and frees the same few per-state tensors (megabytes each). glibc hands blocks that
    large to mmap, or trims them off its heap, so every step faulted its tensors' pages in afresh: ~4,000
    page faults per step of a 576-state 32-network fit, a quarter of its time. With mmap reserved for blocks
    over 256 MB and the heap trimmed only past `KEPT_HEAP`, later steps reuse the pages. The settings stay
    for the rest of the process (glibc cannot report the ones they replace); the fit's freed memory goes back
    at its end. Elsewhere than glibc (macOS, musl) this does nothing.
    """
    libc = _glibc()
    if libc is not None:
        libc.mallopt(_M_MMAP_THRESHOLD, 1 << 28)
        libc.mallopt(_M_TRIM_THRESHOLD, KEPT_HEAP)
    try:
        yield
    finally:
        if libc is not None:
            libc.malloc_trim(0)


def _glibc() -> ctypes.CDLL | None:
    """The C library when it is glibc (it has mallopt and malloc_trim), else None."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return None
    try:
        return ctypes.CDLL("libc.so.6")
    except OSError:
        return None
