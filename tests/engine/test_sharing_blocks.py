"""Sharing blocks: the all-states sharing loss estimated on one random block of states per step."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch

from metairl_engine import FitConfig
from metairl_engine.config import sharing_block_count
from metairl_engine.fit import _Problem, fit, objective, sharing_blocks
from metairl_engine.grids import grid_mdp
from metairl_engine.metrics import pearson
from metairl_engine.networks import StackedMLP
from tests.engine.helpers import as_sparse, small_grid, soft_demos, task
from tests.engine.test_fit import bump_reward, terrain_tasks


def test_blocks_partition_the_states_and_keep_the_directions_of_a_cell_together() -> None:
    mdp = grid_mdp(width=6, height=5, velocity=True, gamma=0.9)  # 30 cells × 8 directions
    blocks = sharing_blocks([mdp, mdp], 4, seed=0)
    everything = np.concatenate(blocks)
    assert np.array_equal(np.sort(everything), np.arange(mdp.n_states))
    assert max(len(b) for b in blocks) - min(len(b) for b in blocks) <= 8
    cells = mdp.n_states // 8
    block_of = np.empty(mdp.n_states, dtype=np.int64)
    for b, states in enumerate(blocks):
        block_of[states] = b
    # direction d of cell c is state d·cells + c; its 8 directions share their successors
    assert (block_of.reshape(8, cells) == block_of[:cells]).all()


def test_more_blocks_than_groups_of_states_give_one_block_per_group_and_a_fit_runs() -> None:
    mdp = grid_mdp(width=3, height=2, velocity=True, gamma=0.9)  # 6 cells: 6 groups of 8 states
    blocks = sharing_blocks([mdp], 20, seed=0)
    assert sorted(len(b) for b in blocks) == [8] * 6
    demos = soft_demos(mdp, np.linspace(0, 1, mdp.n_states), starts=np.array([0, 9]), length=3, seed=0)
    result = fit([task(mdp, demos)], FitConfig(sharing_blocks=20, max_steps=5))
    assert len(result.history) == 5 and np.isfinite(result.rewards).all()


def test_states_of_a_stochastic_mdp_are_split_one_by_one() -> None:
    mdp = as_sparse(small_grid(size=4))
    blocks = sharing_blocks([mdp], 3, seed=1)
    assert sorted(len(b) for b in blocks) == [5, 5, 6]
    assert np.array_equal(np.sort(np.concatenate(blocks)), np.arange(16))


def test_blocks_are_automatic_only_from_four_blocks_of_8192_states() -> None:
    auto = FitConfig()
    assert sharing_block_count(auto, n_states=1_024) == 1
    assert sharing_block_count(auto, n_states=32_767) == 1
    assert sharing_block_count(auto, n_states=32_768) == 4
    assert sharing_block_count(auto, n_states=80_000) == 9
    assert sharing_block_count(FitConfig(sharing_blocks=3), n_states=1_024) == 3
    assert sharing_block_count(FitConfig(sharing_blocks=50), n_states=16) == 16


def test_block_sharing_losses_weighted_by_block_size_add_up_to_the_all_states_loss() -> None:
    mdp = small_grid(size=5)
    reward = bump_reward(5)
    tasks = [task(mdp, soft_demos(mdp, reward, starts=np.array([0, 7]), length=4, seed=s)) for s in (0, 1)]
    losses = {}
    for n_blocks in (1, 3):
        config = FitConfig(sharing="l2", sharing_blocks=n_blocks, ensemble=1, hidden=(6,))
        problem = _Problem(tasks, config)
        gen = torch.Generator().manual_seed(0)
        vr = StackedMLP(n_members=2, n_inputs=2, hidden=(6,), tabular=False, generator=gen)
        base = StackedMLP(n_members=1, n_inputs=2, hidden=(6,), tabular=False, generator=gen)
        with torch.no_grad():
            losses[n_blocks] = [
                (len(b.base_states), objective(problem, b, vr(b.inputs_u), base(b.inputs_base), config)[2])
                for b in problem.blocks
            ]
    ((n_all, whole),) = losses[1]
    assert n_all == 25 and [n for n, _ in losses[3]] != [25]
    weighted = torch.stack([n * shared for n, shared in losses[3]]).sum(dim=0) / n_all
    assert torch.allclose(weighted, whole, atol=1e-6)


def test_a_fit_on_sharing_blocks_learns_about_the_rewards_of_a_fit_on_all_states() -> None:
    tasks, sims = terrain_tasks(seed=0, n_tasks=4, n_demos=3)
    # the blocks against every state on the demonstrator's own steps (the stays added where demonstrations stop
    # move one world's accuracy by ±0.2 either way: `benchmarks.ablation` measures them over ten)
    config = FitConfig(max_steps=300, stay_at_ends=False)
    whole = fit(tasks, replace(config, sharing_blocks=1))
    blocked = fit(tasks, replace(config, sharing_blocks=4))
    for i, sim in enumerate(sims):
        not_goal = np.arange(len(sim.true_reward)) != sim.goal
        assert pearson(blocked.rewards[i], whole.rewards[i], mask=not_goal) > 0.8
    accuracy = [
        np.mean(
            [
                pearson(r.rewards[i], s.true_reward, mask=np.arange(len(s.true_reward)) != s.goal)
                for i, s in enumerate(sims)
            ]
        )
        for r in (whole, blocked)
    ]
    assert accuracy[1] > accuracy[0] - 0.1
