"""COP from forces and moments in either plate frame, the axes a file declares, unloaded samples."""

from __future__ import annotations

import numpy as np
import pytest

from metairl_engine import InvalidInput
from metairl_engine.motion.force_plate import (
    PlateAxes,
    length_unit,
    loaded_span,
    loaded_stretches,
    wrench_cop,
)


@pytest.mark.parametrize("z_up", [True, False])
@pytest.mark.parametrize("depth", [0.0, 0.04])
@pytest.mark.parametrize("reaction", [False, True], ids=["applied", "reaction"])
def test_wrench_cop_finds_where_a_load_acts_whatever_the_frame_and_sign(
    z_up: bool, depth: float, reaction: bool
) -> None:
    """A load with shear acting at r on a surface `depth` above (z up) or below (z down) the origin."""
    rng = np.random.default_rng(0)
    r = np.column_stack([rng.uniform(-0.2, 0.2, 50), rng.uniform(-0.2, 0.2, 50)])
    down = -1.0 if z_up else 1.0  # the load pushes the plate down
    force = np.column_stack([rng.normal(0, 20, 50), rng.normal(0, 20, 50), down * rng.uniform(200, 800, 50)])
    point = np.column_stack([r, np.full(50, depth if z_up else -depth)])
    moment = np.cross(point, force)
    sign = -1.0 if reaction else 1.0
    cop = wrench_cop(sign * force, sign * moment, z_up=z_up, origin_depth=depth)
    np.testing.assert_allclose(cop, r, atol=1e-12)


def test_an_amti_plate_facing_forward_has_x_left_and_z_down() -> None:
    amti = PlateAxes(x="left", y="forward")
    assert not amti.z_up and PlateAxes().z_up and amti.issues() == []
    np.testing.assert_array_equal(amti.to_patient(np.array([[0.1, 0.2]])), [[-0.1, 0.2]])
    np.testing.assert_array_equal(
        PlateAxes(x="forward", y="left").to_patient(np.array([[0.1, 0.2]])), [[-0.2, 0.1]]
    )


def test_axes_along_one_line_are_an_issue() -> None:
    (issue,) = PlateAxes(x="left", y="right").issues()
    assert issue.pointer == "/plate/axes/y" and "perpendicular" in issue.message


def test_loaded_span_cuts_stepping_on_and_off() -> None:
    fz = np.array([0.0, 5.0, 600.0, -650.0, 700.0, 3.0, np.nan])
    assert loaded_span(fz, 20.0) == slice(2, 5)


def test_an_unloaded_sample_between_loaded_ones_is_named() -> None:
    with pytest.raises(InvalidInput) as caught:
        loaded_span(np.array([600.0, 600.0, 2.0, 1.0, 600.0]), 20.0)
    (issue,) = caught.value.issues
    assert issue.pointer == "/samples/2/fz" and "2 such samples" in issue.message


def test_a_plate_never_loaded_is_an_issue_giving_the_largest_force() -> None:
    with pytest.raises(InvalidInput, match=r"no sample has \|Fz\| ≥ 20 N \(the largest is 3 N\)"):
        loaded_span(np.array([0.0, -3.0, 1.0]), 20.0)


@pytest.mark.parametrize(
    ("written", "unit"),
    [
        ("m", "m"),
        ("mete", "m"),
        ("METRES", "m"),
        ("mm\0\0", "mm"),
        ("millim", "mm"),
        ("cent", "cm"),
        ("cm ", "cm"),
    ],
)
def test_unit_strings_are_read_leniently(written: str, unit: str) -> None:
    assert length_unit(written) == unit


@pytest.mark.parametrize("written", ["", "me", "inch", "volts"])
def test_a_string_naming_no_length_unit_is_none(written: str) -> None:
    assert length_unit(written) is None


def test_loaded_stretches_are_the_runs_above_the_threshold() -> None:
    fz = np.array([0, 30, 30, 5, 30, 30, 30, 0, 25], dtype=float)
    assert loaded_stretches(fz, 20.0) == [slice(1, 3), slice(4, 7), slice(8, 9)]
    assert loaded_stretches(np.zeros(4), 20.0) == []
