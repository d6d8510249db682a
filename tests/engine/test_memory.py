"""The memory estimate of a fit: its terms follow the fit's own tensors and grow with what they hold; and the
heap a fit keeps for reuse while it runs goes back to the system when it ends."""

from __future__ import annotations

import os
import platform
from dataclasses import replace

import numpy as np
import pytest
import torch

from metairl_engine.config import FitConfig, ensemble_size
from metairl_engine.coordinates import TASK_COORDINATE_COLUMNS
from metairl_engine.fit import _Problem
from metairl_engine.memory import COORDINATE_COLUMNS, FLOAT, PARAMETER_COPIES, fit_memory, retained_heap
from metairl_engine.networks import StackedMLP
from tests.engine.helpers import small_grid, soft_demos, task


def estimate(config: FitConfig, **sizes: int) -> int:
    """The estimated peak of a deterministic fit of these sizes (defaults: 2 tasks, 400 states, 4 actions)."""
    shape = {"n_tasks": 2, "n_states": 400, "n_actions": 4, "n_steps": 200, "n_mdps": 1} | sizes
    return fit_memory(config, n_features=None, **shape).total


def test_network_memory_is_every_parameter_of_the_fit_networks_five_times() -> None:
    config = FitConfig(hidden=(64, 32), tabular_inputs="one_hot")
    k = ensemble_size(config, n_tasks=3, n_states=500)
    generator = torch.Generator().manual_seed(0)
    vr = StackedMLP(n_members=3 * k, n_inputs=500, hidden=config.hidden, tabular=True, generator=generator)
    base = StackedMLP(n_members=k, n_inputs=500, hidden=config.hidden, tabular=True, generator=generator)
    n_parameters = sum(p.numel() for net in (vr, base) for p in net.parameters())
    memory = fit_memory(config, n_tasks=3, n_states=500, n_actions=4, n_features=None, n_steps=300, n_mdps=1)
    assert memory.networks == PARAMETER_COPIES * n_parameters * FLOAT


def test_estimate_grows_with_hidden_units_states_tasks_and_members() -> None:
    small = estimate(FitConfig(hidden=(32,)))
    assert estimate(FitConfig(hidden=(1024, 1024))) > small
    assert estimate(FitConfig(hidden=(32,)), n_states=40_000) > small
    assert estimate(FitConfig(hidden=(32,)), n_tasks=8) > small
    assert estimate(FitConfig(hidden=(32,), ensemble=8)) > estimate(FitConfig(hidden=(32,), ensemble=1))
    assert 0 < estimate(FitConfig(hidden=())) < small  # no hidden layer: the networks are affine


def test_sharing_on_all_states_holds_rows_per_network_and_state() -> None:
    sizes = {"n_tasks": 4, "n_states": 90_000, "n_actions": 8, "n_features": 2, "n_steps": 2_000, "n_mdps": 1}
    every_state = fit_memory(FitConfig(ensemble=1), **sizes)
    visited = fit_memory(FitConfig(ensemble=1, sharing_states="visited"), **sizes)
    assert every_state.rows > 10 * visited.rows
    assert every_state.rows >= 4 * 90_000 * 8 * 8  # a gather index per network, state and action


def test_advice_names_the_config_that_shrinks_the_largest_part() -> None:
    wide = fit_memory(
        FitConfig(hidden=(4096, 4096)),
        n_tasks=2,
        n_states=100,
        n_actions=4,
        n_features=2,
        n_steps=50,
        n_mdps=1,
    )
    assert "config.hidden" in wide.advice()
    many = fit_memory(
        FitConfig(hidden=(8,)), n_tasks=16, n_states=80_000, n_actions=8, n_features=2, n_steps=50, n_mdps=1
    )
    assert "fewer states or tasks" in many.advice()


def resident_bytes() -> int:
    """This process's resident memory (Linux)."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="the heap is kept for reuse only with glibc")
def test_memory_freed_during_a_fit_is_kept_for_reuse_and_returned_at_its_end() -> None:
    size = 64 * 2**20
    with retained_heap():
        pass  # returns what the heap keeps: memory freed since an earlier fit in this process stays resident
    before = resident_bytes()
    with retained_heap():
        block = torch.ones(size // FLOAT)  # a per-state tensor of a large fit, then freed
        del block
        kept = resident_bytes() - before
    returned = resident_bytes() - before
    assert kept > size // 2 and returned < size // 4


def test_an_mdp_without_features_is_counted_with_the_coordinates_the_fit_gives_it() -> None:
    sizes = {"n_tasks": 3, "n_states": 20_000, "n_actions": 8, "n_steps": 300, "n_mdps": 1}
    one_hot = fit_memory(FitConfig(tabular_inputs="one_hot"), n_features=None, **sizes)
    coordinates = fit_memory(FitConfig(), n_features=None, **sizes)
    # as if the MDP had the coordinates as features (the task networks are not given them twice)
    as_features = fit_memory(FitConfig(task_coordinates=False), n_features=COORDINATE_COLUMNS, **sizes)
    assert coordinates.networks == as_features.networks
    assert coordinates.networks < one_hot.networks / 100  # no embedding row per state and network
    assert coordinates.inputs > as_features.inputs


def test_task_coordinates_are_counted_as_the_columns_the_fit_adds_to_the_task_networks_inputs() -> None:
    mdp = replace(small_grid(size=5), features=np.random.default_rng(0).random((25, 3)).astype(np.float32))
    tasks = [task(mdp, soft_demos(mdp, np.arange(25.0), starts=np.arange(25), length=4, seed=0))]
    config = FitConfig(fourier_octaves=1)
    problem = _Problem(tasks, config)
    octave_columns = 1 + 2 * config.fourier_octaves
    assert problem.features is not None
    assert problem.features.shape[1] == (3 + TASK_COORDINATE_COLUMNS) * octave_columns
    sizes = {"n_tasks": 1, "n_states": 25, "n_actions": 4, "n_features": 3, "n_steps": 100, "n_mdps": 1}
    with_coordinates = fit_memory(config, **sizes)
    without = fit_memory(replace(config, task_coordinates=False), **sizes)
    # every task network's first layer reads the added columns: one weight per column and hidden unit
    first_layer = problem.n_nets * TASK_COORDINATE_COLUMNS * octave_columns * config.hidden[0]
    assert with_coordinates.networks - without.networks == PARAMETER_COPIES * first_layer * FLOAT
    assert with_coordinates.inputs > without.inputs
