"""`readout.agreement`: the verdict on a learned per-direction readout against the recordings' peak reach."""

from __future__ import annotations

import numpy as np

from metairl_engine.grids import DIRECTION_NAMES, grid_mdp, velocity_coords
from metairl_engine.motion.readout import agreement, direction_readout

RNG = np.random.default_rng(0)
REACH = {d: list(0.10 + 0.01 * k + 0.002 * RNG.standard_normal(3)) for k, d in enumerate(DIRECTION_NAMES)}
"""Peak reach of 3 repetitions per direction, rising clearly from `right` to `backward right`."""


def test_a_readout_ranked_like_the_reach_agrees() -> None:
    found = agreement({d: float(k) for k, d in enumerate(DIRECTION_NAMES)}, REACH)
    assert found.verdict == "agrees" and found.spearman == 1.0
    assert found.p_positive is not None and found.p_positive < 0.001
    assert "consistent" in found.detail


def test_a_readout_ranked_against_the_reach_disagrees() -> None:
    found = agreement({d: -float(k) for k, d in enumerate(DIRECTION_NAMES)}, REACH)
    assert found.verdict == "disagrees" and found.spearman == -1.0
    assert "not the patient's preference" in found.detail


def test_favouring_the_clearly_shortest_reach_disagrees_even_without_a_significant_rank_correlation() -> None:
    weak = {d: [0.12, 0.121, 0.119] for d in DIRECTION_NAMES} | {"right": [0.06, 0.061, 0.059]}
    learned = {d: 0.0 for d in DIRECTION_NAMES} | {"right": 1.0, "left": 0.5, "forward": -0.5}
    found = agreement(learned, weak)
    assert found.verdict == "disagrees" and "favours right most" in found.detail


def test_reach_that_does_not_order_the_directions_leaves_it_undetermined() -> None:
    noisy = {
        d: list(0.1 + 0.03 * np.random.default_rng(k).standard_normal(3))
        for k, d in enumerate(DIRECTION_NAMES)
    }
    found = agreement({d: float(k) for k, d in enumerate(DIRECTION_NAMES)}, noisy)
    assert found.verdict == "undetermined"
    assert found.p_positive is not None and found.p_positive > 0.05
    assert found.detail.startswith("Do not read the learned ranking as the patient's preference")


def test_too_few_directions_are_undetermined() -> None:
    three = DIRECTION_NAMES[:3]
    found = agreement({d: float(k) for k, d in enumerate(three)}, REACH)
    assert found.verdict == "undetermined" and found.spearman is None and found.n_directions == 3
    assert agreement({}, REACH).verdict == "undetermined"


def test_directions_without_a_learned_value_or_movements_are_left_out() -> None:
    learned: dict[str, float | None] = {d: float(k) for k, d in enumerate(DIRECTION_NAMES)} | {"left": None}
    found = agreement(learned, {d: r for d, r in REACH.items() if d != "right"})
    assert found.n_directions == 6 and found.verdict == "agrees"


def test_the_direction_readout_favours_the_side_a_reward_is_higher_on() -> None:
    size = 9
    mdp = grid_mdp(width=size, height=size, velocity=True, gamma=0.9)
    x, _, _ = velocity_coords(np.arange(mdp.n_states), width=size, height=size)
    reward = (x - 4.0) / 4  # higher toward the right
    rays = {"right": [(4 + k, 4) for k in range(1, 4)], "left": [(4 - k, 4) for k in range(1, 4)]}
    visited = {d: np.array([cy * size + cx for cx, cy in cells]) for d, cells in rays.items()}  # channel 0
    found = direction_readout(reward, visited, width=size, height=size)
    assert found["right"] > 0 > found["left"]
