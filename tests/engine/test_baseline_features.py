"""`FitConfig.baseline_features`: a baseline network that sees some feature columns only (motion: the cell)."""

import numpy as np
import pytest

from metairl_engine import MDP, FitConfig, InvalidInput, Trajectory
from metairl_engine.fit import fit
from metairl_engine.grids import grid_mdp, velocity_state
from metairl_engine.results import TaskData

SIZE = 6


def ray(direction: int, dx: int, dy: int) -> Trajectory:
    """Out from the centre cell along (dx, dy) for two cells, velocity ``direction``."""
    x = SIZE // 2 + dx * np.arange(3)
    y = SIZE // 2 + dy * np.arange(3)
    return Trajectory.of(velocity_state(x, y, direction, width=SIZE, height=SIZE), np.full(2, direction))


def tasks(mdp: MDP) -> list[TaskData]:
    return [
        TaskData(mdp=mdp, trajectories=[ray(0, 1, 0)] * 3, name="right"),
        TaskData(mdp=mdp, trajectories=[ray(2, 0, 1)] * 3, name="forward"),
    ]


def test_a_cell_baseline_is_the_same_in_every_velocity_channel() -> None:
    mdp = grid_mdp(width=SIZE, height=SIZE, velocity=True, gamma=0.9)
    config = FitConfig(max_steps=5, holdout_fraction=0.0, baseline_features=(0, 1))
    baseline = fit(tasks(mdp), config).baseline.reshape(8, SIZE, SIZE)
    np.testing.assert_array_equal(baseline, np.broadcast_to(baseline[0], baseline.shape))
    full = fit(tasks(mdp), FitConfig(max_steps=5, holdout_fraction=0.0)).baseline.reshape(8, SIZE, SIZE)
    assert not np.allclose(full, full[0])


def test_baseline_features_round_trip_and_are_validated() -> None:
    config = FitConfig(baseline_features=(0, 1))
    assert config.to_dict()["baseline_features"] == [0, 1]
    assert FitConfig.from_dict(config.to_dict()) == config
    assert FitConfig().to_dict()["baseline_features"] is None
    for bad in ((), (0, 0), (-1,)):
        with pytest.raises(InvalidInput) as exc:
            FitConfig(baseline_features=bad)
        assert exc.value.issues[0].pointer == "/config/baseline_features"


def test_baseline_features_must_exist_in_the_mdp() -> None:
    mdp = grid_mdp(width=SIZE, height=SIZE, velocity=True, gamma=0.9)
    with pytest.raises(InvalidInput) as exc:
        fit(tasks(mdp), FitConfig(max_steps=2, baseline_features=(0, 10)))
    assert exc.value.issues[0].pointer == "/config/baseline_features"
    assert "10 feature columns" in exc.value.issues[0].message
