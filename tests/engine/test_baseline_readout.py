"""`ring_centred`: a baseline's part that out-and-back movements identify (differences at equal distance)."""

import numpy as np

from metairl_engine.grids import velocity_coords
from metairl_engine.motion.readout import BASELINE_CAVEAT, ring_centred

SIZE = 9


def test_a_function_of_distance_alone_is_removed_and_differences_within_a_ring_stay() -> None:
    states = np.arange(8 * SIZE * SIZE)
    x, y, _ = velocity_coords(states, width=SIZE, height=SIZE)
    radial = np.round(np.hypot(x - 4, y - 4)) ** 2  # constant on each 1-cell ring
    np.testing.assert_allclose(ring_centred(radial, width=SIZE, height=SIZE, states=states), 0.0, atol=1e-12)
    sided = radial + (x < 4)  # the left side higher by 1
    centred = ring_centred(sided, width=SIZE, height=SIZE, states=states)
    ring = np.round(np.hypot(x - 4, y - 4)) == 3
    assert np.all(centred[ring & (x < 4)] > 0) and np.all(centred[ring & (x > 4)] < 0)


def test_only_the_given_states_enter_the_ring_means_in_their_order() -> None:
    reward = np.arange(8 * SIZE * SIZE, dtype=float)
    states = np.array([40, 41, 39, 31])  # cell (4, 4) and three neighbours at distance 1
    centred = ring_centred(reward, width=SIZE, height=SIZE, states=states)
    assert centred[0] == 0.0  # alone in ring 0
    np.testing.assert_allclose(centred[1:], reward[states[1:]] - reward[states[1:]].mean())


def test_the_caveat_names_what_is_not_identified() -> None:
    assert "distance from the centre" in BASELINE_CAVEAT
