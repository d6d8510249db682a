"""Coordinates for MDPs without features: from a layout, or recovered from the transition graph."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from metairl_engine import MDP, FitConfig, TaskData
from metairl_engine.coordinates import features_are_positions, graph_coordinates, state_coordinates
from metairl_engine.fit import fit
from metairl_engine.grids import grid_mdp, layout_features
from metairl_engine.metrics import pearson
from metairl_engine.sim.terrain import make_tasks, make_world


def featureless(mdp: MDP, *, keep_layout: bool) -> MDP:
    """The same transitions with no features (and its layout kept or dropped)."""
    return replace(mdp, features=None, layout=mdp.layout if keep_layout else None)


@pytest.mark.parametrize("velocity", [False, True])
def test_layout_coordinates_are_the_features_a_grid_mdp_gets(velocity: bool) -> None:
    grid = grid_mdp(width=5, height=4, velocity=velocity, gamma=0.9)
    assert grid.layout is not None and grid.features is not None
    assert np.array_equal(layout_features(grid.layout), grid.features)
    coords = state_coordinates([featureless(grid, keep_layout=True)], seed=0)
    assert coords is not None and np.array_equal(coords, grid.features)


@pytest.mark.parametrize("slip", [0.0, 0.3])
def test_graph_coordinates_recover_a_grid_s_two_axes(slip: float) -> None:
    grid = grid_mdp(width=12, height=9, moves=8, stay=True, slip=slip, gamma=0.9)
    coords = state_coordinates([featureless(grid, keep_layout=False)], seed=0)
    assert coords is not None and coords.shape == (108, 2) and grid.features is not None
    assert coords.min() == 0.0 and coords.max() == 1.0
    design = np.column_stack([coords, np.ones(len(coords))])
    for axis in grid.features.T:  # x and y are (almost) linear in the recovered coordinates, up to rotation
        fitted = design @ np.linalg.lstsq(design, axis, rcond=None)[0]
        assert np.corrcoef(fitted, axis)[0, 1] > 0.95


def test_graph_coordinates_of_disconnected_or_static_states() -> None:
    two_islands = MDP.build(gamma=0.9, next_state=np.array([[1], [0], [3], [2]]))
    coords = graph_coordinates([two_islands], seed=0)
    assert coords is not None and np.isfinite(coords).all()
    assert np.linalg.norm(coords[0] - coords[2]) > np.linalg.norm(coords[0] - coords[1])  # islands lie apart
    standing_still = MDP.build(gamma=0.9, next_state=np.array([[0], [1], [2]]))
    assert graph_coordinates([standing_still], seed=0) is not None  # far apart: one hop beyond reach
    assert graph_coordinates([MDP.build(gamma=0.9, next_state=np.array([[0]]))], seed=0) is None


def test_a_featureless_terrain_is_learned_far_better_with_coordinates_than_one_hot() -> None:
    world = make_world(size=10, n_hills=4, seed=3)
    sims = make_tasks(world, n_tasks=4, n_demos=3, seed=7)
    tabular = featureless(world.mdp, keep_layout=False)
    tasks = [TaskData(tabular, s.trajectories, s.name) for s in sims]

    def accuracy(config: FitConfig) -> float:
        rewards = fit(tasks, config).rewards
        return float(
            np.mean(
                [
                    pearson(r, s.true_reward, mask=np.arange(tabular.n_states) != s.goal)
                    for r, s in zip(rewards, sims, strict=True)
                ]
            )
        )

    default, one_hot = accuracy(FitConfig()), accuracy(FitConfig(tabular_inputs="one_hot"))
    assert default > one_hot + 0.1 and default > 0.3
    assert replace(FitConfig(), tabular_inputs="one_hot").to_dict()["tabular_inputs"] == "one_hot"


def test_features_that_are_each_cells_place_in_any_units_are_positions() -> None:
    from metairl_engine.sim.fourrooms import make_four_rooms

    rooms = make_four_rooms(seed=0).mdp
    assert rooms.features is not None and rooms.layout is None
    assert features_are_positions([rooms], rooms.features)
    assert features_are_positions([rooms], rooms.features * np.float32(0.1) + np.float32(3.0))
    eight = grid_mdp(width=5, height=4, moves=8, stay=True, gamma=0.9)
    assert eight.features is not None and features_are_positions([eight], eight.features)


def test_features_that_describe_more_than_the_place_or_repeat_on_two_states_are_not_positions() -> None:
    from metairl_engine.sim.objectworld import make_objectworld

    world = make_objectworld(seed=0, size=8)[0].mdp
    assert world.features is not None and not features_are_positions([world], world.features)
    grid = grid_mdp(width=4, height=4, gamma=0.9)
    assert grid.features is not None
    rows_only = grid.features[:, 1:]  # the row alone: four states share each value
    assert not features_are_positions([grid], rows_only)
    with_terrain = np.concatenate([grid.features, np.arange(16, dtype=np.float32)[:, None] ** 2], axis=1)
    assert not features_are_positions([grid], with_terrain)
