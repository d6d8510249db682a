"""`readout.agreement`: the verdict on a learned per-direction readout against the recordings' peak reach and the
way their paths bend."""

from __future__ import annotations

import numpy as np

from metairl_engine.grids import DIRECTION_NAMES, grid_mdp, velocity_coords
from metairl_engine.motion.readout import agreement, bend_levels, direction_readout

RNG = np.random.default_rng(0)
REACH = {d: list(0.10 + 0.01 * k + 0.002 * RNG.standard_normal(3)) for k, d in enumerate(DIRECTION_NAMES)}
"""Peak reach of 3 repetitions per direction, rising clearly from `right` to `backward right`."""

ANGLES = np.arange(8) * np.pi / 4
OFFSETS = {
    d: [o - 0.02, o, o + 0.02]
    for d, o in zip(DIRECTION_NAMES, -np.sin(ANGLES - np.radians(100)), strict=True)
}
"""Three repetitions' path offsets per direction of a patient drawn toward 100° (between forward and forward
left): each path bends by the slope of cos(θ − 100°) at its direction."""
BEND = dict(
    zip(DIRECTION_NAMES, bend_levels(np.array([np.mean(OFFSETS[d]) for d in DIRECTION_NAMES])), strict=True)
)
"""The path-bend level per direction those offsets give: highest at forward, lowest at backward."""
FLAT = {d: [0.11, 0.12, 0.13] for d in DIRECTION_NAMES}
"""Peak reach that does not order the directions: every direction alike."""


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


def test_a_readout_ranked_against_the_bend_disagrees_where_the_reach_says_nothing() -> None:
    found = agreement({d: -v for d, v in BEND.items()}, FLAT, offsets=OFFSETS)
    assert found.verdict == "disagrees" and found.bend_spearman == -1.0
    assert found.bend_p_negative is not None and found.bend_p_negative < 0.001
    assert found.bend_rho_high is not None and found.bend_rho_high < 0
    assert "against the path bend" in found.detail
    assert (
        agreement({d: -v for d, v in BEND.items()}, FLAT).verdict == "undetermined"
    )  # the reach alone cannot tell


def test_a_readout_ranked_like_the_reach_but_against_the_bend_disagrees() -> None:
    reach = {
        d: [v - 0.01, v, v + 0.01]
        for d, v in zip(DIRECTION_NAMES, 0.12 - 0.1 * np.array(list(BEND.values())), strict=True)
    }
    learned = {d: -v for d, v in BEND.items()}
    assert agreement(learned, reach).verdict == "agrees"
    found = agreement(learned, reach, offsets=OFFSETS)
    assert found.verdict == "disagrees" and found.spearman == 1.0 and found.bend_spearman == -1.0


def test_a_readout_ranked_like_both_the_reach_and_the_bend_agrees() -> None:
    reach = {
        d: [v - 0.01, v, v + 0.01]
        for d, v in zip(DIRECTION_NAMES, 0.12 + 0.1 * np.array(list(BEND.values())), strict=True)
    }
    found = agreement(BEND, reach, offsets=OFFSETS)
    assert found.verdict == "agrees" and found.spearman == 1.0 and found.bend_spearman == 1.0
    assert found.bend_p_positive is not None and found.bend_p_positive < 0.001
    assert "path bend" in found.detail and "peak reach" in found.detail


def test_a_readout_favouring_the_least_reached_direction_is_not_endorsed_by_the_bend() -> None:
    top = max(BEND, key=BEND.__getitem__)
    # the reach ranks the directions as the bend does except the favourite, reached least; its repetitions
    # spread too widely for that to be a clear contradiction
    means = {d: 0.12 + 0.01 * v for d, v in BEND.items()} | {top: 0.10}
    reach = {d: [m - 0.05, m, m + 0.05] for d, m in means.items()}
    found = agreement(BEND, reach, offsets=OFFSETS)
    assert found.bend_spearman == 1.0 and found.spearman is not None and found.spearman > 0
    assert found.verdict == "undetermined"


def test_without_a_bend_for_all_eight_directions_the_verdict_falls_back_to_the_reach_alone() -> None:
    learned = {d: float(k) for k, d in enumerate(DIRECTION_NAMES)}
    alone = agreement(learned, REACH)
    missing = {d: o for d, o in OFFSETS.items() if d != "left"} | {"forward": []}
    for offsets in (None, missing, {d: o for d, o in OFFSETS.items() if d != "left"}):
        found = agreement(learned, REACH, offsets=offsets)
        assert found == alone and found.verdict == "agrees"
        assert found.bend_spearman is None and found.bend_p_positive is None and found.bend_rho_low is None


def test_one_path_per_direction_bounds_nothing_so_the_bend_alone_claims_nothing() -> None:
    """A perfect ρ from one path per direction: no repetition to resample, so no interval excludes 0."""
    single = {d: [float(np.mean(o))] for d, o in OFFSETS.items()}
    found = agreement({d: -v for d, v in BEND.items()}, FLAT, offsets=single)
    assert found.bend_spearman == -1.0 and found.verdict == "undetermined", found.detail
    assert (found.bend_rho_low, found.bend_rho_high) == (-1.0, 1.0)
