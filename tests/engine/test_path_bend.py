"""`readout.path_bend`: the preference's level per direction, integrated from which way the paths bend."""

import numpy as np
import pytest

from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS, velocity_state
from metairl_engine.motion.readout import path_bend

SIZE = 11
CENTRE = (SIZE - 1) // 2


def rays(bend_toward: tuple[float, float] | None) -> dict[str, np.ndarray]:
    """Every direction's path: four cells out along its ray, each shifted one cell across the ray toward
    the side ``bend_toward`` (a plate direction) lies on; straight where it lies on the ray or is None."""
    out = {}
    for k, d in enumerate(DIRECTION_NAMES):
        dx, dy = (int(v) for v in DIRECTIONS[k])
        across = np.array([-dy, dx])  # counter-clockwise from the ray
        side = 0 if bend_toward is None else int(np.sign(across @ np.asarray(bend_toward)))
        cells = [
            (CENTRE + t * dx + side * across[0], CENTRE + t * dy + side * across[1]) for t in range(1, 5)
        ]
        out[d] = np.array([velocity_state(x, y, k, width=SIZE, height=SIZE) for x, y in cells])
    return out


def test_paths_bending_toward_forward_rank_forward_highest_and_backward_lowest() -> None:
    found = path_bend(rays((0.0, 1.0)), width=SIZE, height=SIZE)
    assert max(found, key=found.__getitem__) == "forward"
    assert min(found, key=found.__getitem__) == "backward"
    assert found["right"] == pytest.approx(found["left"])  # mirror images
    assert found["forward right"] > found["right"] > found["backward right"]
    assert sum(found.values()) == pytest.approx(0.0, abs=1e-12)


def test_paths_bending_toward_the_right_rank_right_highest() -> None:
    found = path_bend(rays((1.0, 0.0)), width=SIZE, height=SIZE)
    assert max(found, key=found.__getitem__) == "right" and min(found, key=found.__getitem__) == "left"


def test_straight_paths_favour_no_direction() -> None:
    found = path_bend(rays(None), width=SIZE, height=SIZE)
    assert set(found) == set(DIRECTION_NAMES)
    np.testing.assert_allclose(list(found.values()), 0.0, atol=1e-12)


def test_without_all_eight_directions_there_is_no_loop_to_integrate() -> None:
    paths = rays((0.0, 1.0))
    assert path_bend({d: s for d, s in paths.items() if d != "left"}, width=SIZE, height=SIZE) == {}
    assert path_bend(paths | {"left": np.array([], dtype=np.int64)}, width=SIZE, height=SIZE) == {}
