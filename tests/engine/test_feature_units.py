"""Features start at 0, span at least one and change by at most one per move when the networks see them: a fit
does not depend on the origin a lab measures its features from, nor on units that make a feature change by more
than one per move, and features in much finer units are stretched to span one. Each input column starts the
networks at about unit size, however large its values."""

from __future__ import annotations

import numpy as np
import torch

from metairl_engine import FitConfig
from metairl_engine.fit import fit, initial_input_scale, input_units
from metairl_engine.networks import StackedMLP
from tests.engine.helpers import as_sparse, goal_tasks_with_features, small_grid

CONFIG = FitConfig(hidden=(8,), max_steps=40, ensemble=2)


def _distances(size: int = 5) -> np.ndarray:
    """Per state of a size×size grid, the Manhattan distance in cells to each of two corners (S, 2)."""
    y, x = np.divmod(np.arange(size * size), size)
    return np.stack([x + y, (size - 1 - x) + y], axis=1).astype(np.float32)


def test_features_in_units_a_thousand_times_smaller_give_the_same_fit() -> None:
    cells = _distances()
    in_cells, in_thousandths = (
        fit(goal_tasks_with_features(cells), CONFIG),
        fit(goal_tasks_with_features(cells * 1000), CONFIG),
    )
    np.testing.assert_allclose(in_thousandths.rewards, in_cells.rewards, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(in_thousandths.baseline, in_cells.baseline, rtol=1e-4, atol=1e-4)


def test_features_measured_from_another_origin_give_the_same_fit() -> None:
    cells = _distances()
    from_zero, from_forty = (
        fit(goal_tasks_with_features(cells), CONFIG),
        fit(goal_tasks_with_features(cells + 40), CONFIG),
    )
    np.testing.assert_allclose(from_forty.rewards, from_zero.rewards, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(from_forty.baseline, from_zero.baseline, rtol=1e-4, atol=1e-4)


def test_only_columns_changing_by_more_than_one_per_move_are_rescaled() -> None:
    mdp = small_grid(size=5)
    cells = _distances()
    mixed = np.concatenate([cells, cells * 3, cells / 4], axis=1)
    out = input_units(mixed, [mdp])
    np.testing.assert_allclose(out, np.concatenate([cells, cells, cells / 4], axis=1), rtol=1e-6)
    assert input_units(cells, [mdp]) is cells  # nothing to move or rescale: the very array, bit for bit
    np.testing.assert_allclose(input_units(cells - 3, [mdp]), cells, rtol=1e-6)


def test_a_column_spanning_less_than_one_is_stretched_to_span_one() -> None:
    mdp = small_grid(size=5)
    cells = _distances()  # each column spans 8 cells
    out = input_units(np.concatenate([cells / 100, cells], axis=1), [mdp])
    np.testing.assert_allclose(out, np.concatenate([cells / 8, cells], axis=1), rtol=1e-6)


def test_moves_of_a_stochastic_mdp_count_every_possible_successor() -> None:
    sparse = as_sparse(small_grid(size=5))
    assert sparse.next_state is None
    np.testing.assert_allclose(input_units(_distances() * 7, [sparse]), _distances(), rtol=1e-6)


def test_columns_larger_than_unit_size_get_initial_weights_divided_by_their_root_mean_square() -> None:
    rows = torch.tensor([[0.5, 4.0, 10.0], [-0.5, -4.0, 10.0]])  # root mean squares 0.5, 4, 10
    scale = initial_input_scale(rows)
    assert scale is not None
    torch.testing.assert_close(scale, torch.tensor([1.0, 0.25, 0.1]))
    indicators_and_coordinates = torch.tensor([[0.0, 1.0], [1.0, 0.25], [1.0, 0.0]])
    assert initial_input_scale(indicators_and_coordinates) is None  # the default initialisation, untouched


def test_a_columns_initial_contribution_does_not_grow_with_its_size() -> None:
    distances = torch.from_numpy(_distances())  # each column spans 8 cells: root mean square above 1

    def initial_reward(inputs: torch.Tensor) -> torch.Tensor:
        net = StackedMLP(
            n_members=2,
            n_inputs=2,
            hidden=(6, 3),
            tabular=False,
            generator=torch.Generator().manual_seed(0),
            input_scale=initial_input_scale(inputs),
        )
        with torch.no_grad():
            return net(inputs)

    five_times = distances * torch.tensor([1.0, 5.0])
    torch.testing.assert_close(initial_reward(five_times), initial_reward(distances), rtol=1e-5, atol=1e-5)
    unscaled = StackedMLP(
        n_members=2, n_inputs=2, hidden=(6, 3), tabular=False, generator=torch.Generator().manual_seed(0)
    )
    with torch.no_grad():
        assert not torch.allclose(unscaled(five_times), initial_reward(five_times), atol=1e-3)
