"""Kinematic readout: descriptors of known movements, bootstrap intervals, session comparison, figure."""

from io import BytesIO

import numpy as np
import pytest
from PIL import Image

from metairl_engine.motion.kinematics import (
    DESCRIPTORS,
    KinematicSettings,
    Movement,
    compare,
    compare_recordings,
    comparison_figure,
    comparison_png,
    motion_summary,
    movements,
    summarise,
)
from metairl_engine.motion.recording import Bounds, Recording
from metairl_engine.sim.controller_patient import ControllerSettings, simulate_controller_patient

PLATE = Bounds(x_min=-1.0, x_max=1.0, y_min=-1.0, y_max=1.0)
RATE = 100.0


def out_and_back(directions: list[tuple[str, float, float]], *, rest_s: float = 1.0) -> Recording:
    """A noiseless recording: for each (instruction, reach, duration of the way out) rest at the centre, move
    straight out at constant speed along the instruction, and straight back in the same time."""
    units = {"right": (1.0, 0.0), "forward": (0.0, 1.0), "left": (-1.0, 0.0)}
    xs, ys, labels = [], [], []
    for name, reach, out_s in directions:
        n_rest, n_out = int(rest_s * RATE), int(out_s * RATE)
        ramp = np.r_[np.zeros(n_rest), np.linspace(0, reach, n_out + 1), np.linspace(reach, 0, n_out + 1)[1:]]
        xs.append(ramp * units[name][0])
        ys.append(ramp * units[name][1])
        labels += [""] * n_rest + [name] * (2 * n_out + 1)
    tail = int(rest_s * RATE)
    x, y = np.r_[np.concatenate(xs), np.zeros(tail)], np.r_[np.concatenate(ys), np.zeros(tail)]
    t = np.arange(len(x)) / RATE
    return Recording.build(t=t, x=x, y=y, bounds=PLATE, instruction=labels + [""] * tail)


EXACT = KinematicSettings(smooth_s=0.0, rest_s=0.05, onset_fraction=0.01)


def test_descriptors_of_straight_movements() -> None:
    rec = out_and_back([("right", 0.5, 1.0), ("forward", 0.8, 2.0)])
    right, forward = movements(rec, settings=EXACT)
    assert (right.direction, forward.direction) == ("right", "forward")
    assert right.peak_reach == pytest.approx(0.5)
    assert forward.peak_reach == pytest.approx(0.8)
    assert right.path_length == pytest.approx(1.0, abs=0.03)  # onset and end cut 1 % of the reach
    assert forward.path_length == pytest.approx(1.6, abs=0.03)
    assert right.deviation == pytest.approx(0.0, abs=1e-9)
    assert right.time_to_peak_s == pytest.approx(1.0, abs=0.03)
    assert forward.time_to_peak_s == pytest.approx(2.0, abs=0.05)
    assert right.mean_speed == pytest.approx(0.5, rel=0.03)
    assert forward.mean_speed == pytest.approx(0.4, rel=0.03)


def test_peak_reach_is_measured_along_the_instruction_and_deviation_across_it() -> None:
    rec = out_and_back([("right", 0.6, 1.0)] * 2)
    tilted = Recording.build(  # the same movement, but instructed forward: reach 0 along forward
        t=rec.t,
        x=rec.x,
        y=rec.y,
        bounds=PLATE,
        instruction=np.where(rec.instruction == "right", "forward", ""),
    )
    m = movements(tilted, settings=EXACT)[0]
    assert m.peak_reach == pytest.approx(0.0, abs=1e-9)
    assert m.deviation > 0.2


def moves(direction: str, values: list[float]) -> list[Movement]:
    return [Movement(direction, v, 2 * v, 0.0, 1.0, v) for v in values]


def test_summary_has_the_api_shape_with_intervals_around_the_mean() -> None:
    summary = summarise(moves("forward", [0.4, 0.5, 0.6]) + moves("right", [0.3]))
    assert [r["direction"] for r in summary["directions"]] == ["right", "forward"]
    right, forward = summary["directions"]
    assert forward["n_segments"] == 3 and set(DESCRIPTORS) <= set(forward)
    reach = forward["peak_reach"]
    assert reach["mean"] == pytest.approx(0.5)
    assert 0.4 <= reach["low"] < 0.5 < reach["high"] <= 0.6
    assert right["peak_reach"] == {"mean": pytest.approx(0.3), "low": None, "high": None}  # one repetition


def test_bootstrap_is_seeded() -> None:
    data = moves("left", [0.1, 0.5, 0.2, 0.7, 0.33, 0.91, 0.05, 0.62])
    assert summarise(data) == summarise(data)
    assert summarise(data) != summarise(data, KinematicSettings(seed=1))


def test_comparison_is_b_minus_a_with_an_interval() -> None:
    a = moves("left", [0.20, 0.22, 0.24]) + moves("right", [0.5, 0.5])
    b = moves("left", [0.40, 0.42, 0.44]) + moves("forward", [0.6])
    result = compare(a, b)
    assert [r["direction"] for r in result["directions"]] == ["left"]  # directions both sides have
    (row,) = result["directions"]
    assert (row["n_a"], row["n_b"]) == (3, 3)
    diff = row["peak_reach_diff"]
    assert diff["mean"] == pytest.approx(0.2)
    assert 0.15 < diff["low"] <= 0.2 <= diff["high"] < 0.25
    assert row["path_length_diff"]["mean"] == pytest.approx(0.4)
    assert result["a"] == summarise(a) and result["b"] == summarise(b)


@pytest.fixture(scope="module")
def controller_comparison() -> dict:
    sim = simulate_controller_patient(ControllerSettings(width=20, height=20, repetitions=3))
    return compare_recordings([sim.sessions["unstimulated"]], [sim.sessions["stimulated"]])


def test_the_weak_side_stands_out_and_stimulation_reaches_farther(controller_comparison: dict) -> None:
    for side in ("a", "b"):
        reach = {r["direction"]: r["peak_reach"]["mean"] for r in controller_comparison[side]["directions"]}
        assert len(reach) == 8
        assert min(reach, key=reach.__getitem__) == "left"
    for row in controller_comparison["directions"]:
        assert row["peak_reach_diff"]["low"] > 0, row["direction"]


def test_motion_summary_pools_recordings() -> None:
    rec = out_and_back([("right", 0.5, 1.0), ("forward", 0.8, 1.0)])
    once, twice = motion_summary([rec], settings=EXACT), motion_summary([rec, rec], settings=EXACT)
    assert [r["n_segments"] for r in twice["directions"]] == [2 * r["n_segments"] for r in once["directions"]]


def test_comparison_figure_is_a_png(controller_comparison: dict) -> None:
    png = comparison_png(controller_comparison, names=("unstimulated", "stimulated"), units="m")
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_comparison_figure_titles_state_each_descriptors_unit(controller_comparison: dict) -> None:
    figure = comparison_figure(controller_comparison, units="mm", time_unit="t units")
    titles = {ax.get_title() for ax in figure.axes}
    assert {
        "peak reach (mm)",
        "path length (mm)",
        "deviation from the line (mm)",
        "time to peak (t units)",
        "mean speed (mm / t units)",
    } <= titles


def test_the_polar_plots_labels_stay_clear_of_the_first_panels(controller_comparison: dict) -> None:
    figure = comparison_figure(controller_comparison, names=("unstimulated", "stimulated"))
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    polar, first = (ax.get_tightbbox(renderer) for ax in figure.axes[:2])
    assert polar is not None and first is not None
    assert polar.x1 < first.x0


def test_a_difference_panel_spans_a_twentieth_of_its_descriptor_when_the_differences_are_rounding(
    controller_comparison: dict,
) -> None:
    # float32 times give b − a of ±3e-7 s where the sides agree: the panel reads "no difference" at the
    # descriptor's own scale, not noise on a 1e-7 axis.
    rounding = {"mean": 0.0, "low": -3e-7, "high": 3e-7}
    tied = controller_comparison | {
        "directions": [row | {"time_to_peak_s_diff": rounding} for row in controller_comparison["directions"]]
    }
    panel = comparison_figure(tied).axes[1 + DESCRIPTORS.index("time_to_peak_s")]
    scale = max(r["time_to_peak_s"]["mean"] for s in ("a", "b") for r in tied[s]["directions"])
    low, high = panel.get_xlim()
    assert low <= -0.05 * scale and high >= 0.05 * scale
    reach = comparison_figure(controller_comparison).axes[1 + DESCRIPTORS.index("peak_reach")]
    widest = max(r["peak_reach_diff"]["high"] for r in controller_comparison["directions"])
    assert reach.get_xlim()[1] >= widest  # real differences keep the span that shows them


def test_comparison_figure_states_a_sides_verdict_on_its_learned_readout_under_the_panels(
    controller_comparison: dict,
) -> None:
    verdict = {"verdict": "disagrees", "detail": "The learned readout contradicts the recordings."}
    plain = comparison_png(controller_comparison, names=("a", "b"))
    judged = comparison_png(
        controller_comparison | {"learned": {"a": {"agreement": verdict}, "b": None}}, names=("a", "b")
    )
    height = {name: Image.open(BytesIO(png)).size[1] for name, png in (("plain", plain), ("judged", judged))}
    assert height["judged"] > height["plain"]


def test_a_side_with_one_repetition_is_held_while_the_other_is_resampled() -> None:
    one, three = moves("left", [0.2]), moves("left", [0.40, 0.42, 0.47])
    (row,) = compare(one, three)["directions"]
    alone = summarise(three)["directions"][0]["peak_reach"]  # the same seed draws the same resamples of b
    diff = row["peak_reach_diff"]
    assert diff["low"] == pytest.approx(alone["low"] - 0.2)
    assert diff["high"] == pytest.approx(alone["high"] - 0.2)
    assert diff["low"] < diff["high"]
    (single,) = compare(one, moves("left", [0.5]))["directions"]
    assert single["peak_reach_diff"] == {"mean": pytest.approx(0.3), "low": None, "high": None}
