"""COP recordings → velocity-grid demonstrations: validation, discretisation, segmentation."""

import numpy as np
import pytest

from metairl_engine import InvalidInput, validate_trajectories
from metairl_engine.grids import DIRECTION_NAMES, DIRECTIONS, grid_mdp, velocity_coords, velocity_state
from metairl_engine.motion.recording import (
    NO_INSTRUCTION,
    Bounds,
    DiscretiseSettings,
    Recording,
    SegmentSettings,
    canonical_instruction,
    demonstrations,
    discretise,
    segment,
)

PLATE = Bounds(x_min=0.0, x_max=10.0, y_min=0.0, y_max=10.0)
"""A 10 × 10 plate: with a 10 × 10 grid, cell (i, j) spans [i, i+1) × [j, j+1)."""
EXACT = DiscretiseSettings(width=10, height=10, smooth_s=0.0)


def pointers(exc: pytest.ExceptionInfo[InvalidInput]) -> list[str]:
    return [i.pointer for i in exc.value.issues]


def through_cells(cells: list[tuple[int, int]], instruction: list[str | None] | None = None) -> Recording:
    """A recording at 1 Hz visiting the centres of the given cells of `PLATE`."""
    xy = np.array(cells, dtype=float) + 0.5
    t = np.arange(len(cells), dtype=float)
    return Recording.build(t=t, x=xy[:, 0], y=xy[:, 1], bounds=PLATE, instruction=instruction)


def path_cells(rec: Recording, settings: DiscretiseSettings = EXACT) -> list[tuple[int, int]]:
    path = discretise(rec, settings)
    return list(zip(path.x.tolist(), path.y.tolist(), strict=True))


# --- validation ---------------------------------------------------------------------------------------


def test_valid_recording_normalises_instructions() -> None:
    rec = through_cells([(0, 0), (1, 0)], instruction=[" Forward ", None])
    assert rec.instruction is not None and rec.instruction.tolist() == ["forward", ""]
    assert rec.sample_rate == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("t", "x", "y", "pointer", "words"),
    [
        ([0, 1, 1, 2], [1, 1, 1, 1], [1, 1, 1, 1], "/samples/2/t", "strictly increase"),
        ([0, 2, 1, 3], [1, 1, 1, 1], [1, 1, 1, 1], "/samples/2/t", "strictly increase"),
        ([0, 1, 2, 3], [1, np.nan, 1, 1], [1, 1, 1, 1], "/samples/1/x", "finite"),
        ([0, 1, 2, 3], [1, 1, 1, 1], [1, 1, 1, np.inf], "/samples/3/y", "finite"),
        ([0, 1, 2, 3], [1, 1, 1, 1], [1, 1, 1, 10.5], "/samples/3/y", "outside the plate"),
        ([0, 1, 2, 3], [1, -0.1, 1, 1], [1, 1, 1, 1], "/samples/1/x", "outside the plate"),
        ([], [], [], "/samples", "is empty"),
        ([0], [1], [1], "/samples", "at least 2"),
        ([0, 1, 2], [1, 1], [1, 1, 1], "/samples", "equally long"),
    ],
)
def test_bad_recordings_name_the_sample_and_say_why(
    t: list[float], x: list[float], y: list[float], pointer: str, words: str
) -> None:
    with pytest.raises(InvalidInput) as exc:
        Recording.build(t=t, x=x, y=y, bounds=PLATE)
    assert pointers(exc) == [pointer]
    assert words in str(exc.value)


def test_unknown_instruction_is_named() -> None:
    with pytest.raises(InvalidInput) as exc:
        through_cells([(0, 0), (1, 0), (2, 0)], instruction=["left", "sideways", "left"])
    assert pointers(exc) == ["/samples/1/instruction"]
    assert "'sideways'" in str(exc.value)


def test_several_problems_are_reported_together_in_sample_order() -> None:
    with pytest.raises(InvalidInput) as exc:
        Recording.build(t=[0, 1, 1, 3], x=[1, 1, 1, 11], y=[np.nan, 1, 1, 1], bounds=PLATE)
    assert pointers(exc) == ["/samples/0/y", "/samples/2/t", "/samples/3/x"]


@pytest.mark.parametrize(
    "spelling",
    [
        "forward left",
        "forward_left",
        "forward-left",
        "Forward Left",
        "FORWARD_LEFT",
        " Forward-left ",
        "forward  left",
    ],
)
def test_usual_spellings_of_an_instruction_are_accepted(spelling: str) -> None:
    rec = through_cells([(0, 0), (1, 0)], instruction=[spelling, "backward_right"])
    assert rec.instruction is not None and rec.instruction.tolist() == ["forward left", "backward right"]


@pytest.mark.parametrize("rest", ["rest", "Rest", "none", "None", "", "  ", None, "NaN"])
def test_usual_spellings_of_rest_mean_no_instruction(rest: str | None) -> None:
    rec = through_cells([(0, 0), (1, 0)], instruction=[rest, "left"])
    assert rec.instruction is not None and rec.instruction.tolist() == [NO_INSTRUCTION, "left"]


def test_canonical_instruction() -> None:
    assert canonical_instruction("Backward_Right") == "backward right"
    assert canonical_instruction(np.str_("forward-left")) == "forward left"
    assert canonical_instruction(None) == canonical_instruction(float("nan")) == NO_INSTRUCTION
    assert canonical_instruction("sideways") == "sideways"  # unknown names are the caller's check


def test_instruction_errors_come_in_sample_order_without_numpy_reprs() -> None:
    with pytest.raises(InvalidInput) as exc:
        Recording.build(
            t=[0, 1, 2, 3, 4],
            x=[1, 1, 1, 11, 1],
            y=[1, 1, 1, 1, 1],
            bounds=PLATE,
            instruction=np.array(["left", "zz_backward", "left", "backward_leftt", "aa"]),
        )
    assert pointers(exc) == [
        "/samples/1/instruction",
        "/samples/3/x",
        "/samples/3/instruction",
        "/samples/4/instruction",
    ]
    text = str(exc.value)
    assert "np.str_" not in text and "'zz_backward'" in text and "'backward_leftt'" in text


def test_empty_plate_bounds_are_rejected() -> None:
    with pytest.raises(InvalidInput) as exc:
        Recording.build(t=[0, 1], x=[1, 1], y=[1, 1], bounds=Bounds(0.0, 10.0, 5.0, 5.0))
    assert pointers(exc) == ["/bounds/y_max"]


# --- discretisation -----------------------------------------------------------------------------------


def test_straight_line_becomes_one_move_per_cell() -> None:
    cells = [(2, 5), (3, 5), (4, 5), (5, 5)]
    path = discretise(through_cells(cells), EXACT)
    assert list(zip(path.x.tolist(), path.y.tolist(), strict=True)) == cells
    tr = path.trajectory()
    assert tr.actions.tolist() == [0, 0, 0]  # right
    assert tr.states.tolist() == velocity_state(np.array([2, 3, 4, 5]), 5, 0, width=10, height=10).tolist()


def test_diagonal_moves_use_diagonal_directions() -> None:
    path = discretise(through_cells([(5, 5), (4, 4), (3, 3), (3, 4)]), EXACT)
    assert [DIRECTION_NAMES[d] for d in path.direction[1:]] == ["backward left", "backward left", "forward"]


def test_skipped_cells_are_filled_along_a_straight_king_line() -> None:
    assert path_cells(through_cells([(1, 1), (4, 1)])) == [(1, 1), (2, 1), (3, 1), (4, 1)]
    assert path_cells(through_cells([(0, 0), (3, 3)])) == [(0, 0), (1, 1), (2, 2), (3, 3)]
    cells = path_cells(through_cells([(0, 0), (6, 3), (0, 9)]))
    steps = np.diff(np.array(cells), axis=0)
    assert np.abs(steps).max() == 1 and (np.abs(steps).max(axis=1) == 1).all()  # every step a king move
    assert len(cells) == 1 + 6 + 6 and cells[6] == (6, 3) and cells[-1] == (0, 9)
    # Filled cells stay within half a cell of the straight segment (0,0) → (6,3).
    first = np.array(cells[:7], dtype=float)
    assert np.abs(first[:, 1] - first[:, 0] / 2).max() <= 0.5


def test_pauses_are_dropped_and_cells_remember_the_sample_that_reached_them() -> None:
    path = discretise(through_cells([(1, 1), (1, 1), (1, 1), (2, 1), (2, 1), (4, 1)]), EXACT)
    assert path.x.tolist() == [1, 2, 3, 4]
    assert path.sample.tolist() == [0, 3, 5, 5]


def test_first_state_takes_the_direction_of_the_first_move() -> None:
    path = discretise(through_cells([(5, 5), (5, 6), (4, 6)]), EXACT)
    assert path.direction.tolist() == [2, 2, 4]


def test_smoothing_removes_a_one_sample_flicker_across_a_cell_border() -> None:
    t = np.arange(9, dtype=float) / 100
    x = np.array([1.5, 1.6, 1.7, 2.1, 1.8, 1.9, 2.3, 2.5, 2.6])  # sample 3 flickers into cell 2 and back
    rec = Recording.build(t=t, x=x, y=np.full(9, 5.5), bounds=PLATE)
    raw = discretise(rec, EXACT)
    smooth = discretise(rec, DiscretiseSettings(width=10, height=10, smooth_s=0.05))
    assert raw.x.tolist() == [1, 2, 1, 2]
    assert smooth.x.tolist() == [1, 2]


def test_a_recording_that_never_leaves_its_cell_is_rejected() -> None:
    with pytest.raises(InvalidInput) as exc:
        discretise(through_cells([(3, 3), (3, 3), (3, 3)]), EXACT)
    assert pointers(exc) == ["/samples"] and "never leaves" in str(exc.value)


def test_discretised_trajectories_are_valid_on_the_velocity_grid() -> None:
    rng = np.random.default_rng(0)
    xy = np.clip(5 + np.cumsum(rng.normal(scale=0.7, size=(300, 2)), axis=0), 0, 10)
    rec = Recording.build(t=np.arange(300) / 100, x=xy[:, 0], y=xy[:, 1], bounds=PLATE)
    tr = discretise(rec, EXACT).trajectory()
    validate_trajectories(grid_mdp(width=10, height=10, velocity=True, gamma=0.9), [tr])
    x, y, d = velocity_coords(tr.states, width=10, height=10)
    assert (d[1:] == tr.actions).all()
    assert (x[-1], y[-1]) == (min(int(xy[-1, 0]), 9), min(int(xy[-1, 1]), 9))


# --- segmentation -------------------------------------------------------------------------------------


def out_and_back(
    directions: list[int], *, radius: float = 3.5, rate: float = 100.0, seconds: float = 2.0
) -> tuple[Recording, list[str]]:
    """A clean session: one smooth out-and-back movement from the plate centre per direction index."""
    phase = np.arange(int(seconds * rate)) / (seconds * rate)
    reach = radius * np.sin(np.pi * phase) ** 2
    unit = DIRECTIONS[directions] / np.hypot(*DIRECTIONS[directions].T)[:, None]
    xy = 5.0 + (unit[:, None, :] * reach[None, :, None]).reshape(-1, 2)
    labels = [DIRECTION_NAMES[d] for d in directions]
    instruction = np.repeat(labels, len(phase))
    rec = Recording.build(
        t=np.arange(len(xy)) / rate, x=xy[:, 0], y=xy[:, 1], bounds=PLATE, instruction=instruction
    )
    return rec, labels


def test_segments_split_at_returns_to_the_origin_and_are_labelled_by_direction() -> None:
    order = [2, 6, 4, 0, 1, 5, 3, 7, 2]
    rec, labels = out_and_back(order)
    unlabelled = Recording(t=rec.t, x=rec.x, y=rec.y, bounds=rec.bounds)
    segs = segment(unlabelled)
    assert [s.label for s in segs] == labels
    # Cuts fall at the returns to the centre (every 200 samples).
    assert [s.start for s in segs[1:]] == pytest.approx([200 * k for k in range(1, len(order))], abs=3)
    assert segs[0].start == 0 and segs[-1].stop == len(rec.t)


def test_instruction_column_wins_over_geometry() -> None:
    rec, _ = out_and_back([0, 2])
    assert rec.instruction is not None
    relabelled = Recording(
        t=rec.t, x=rec.x, y=rec.y, bounds=rec.bounds, instruction=np.repeat(["left", "backward"], 200)
    )
    assert [s.label for s in segment(relabelled)] == ["left", "backward"]


def test_only_allowed_directions_are_used_as_labels() -> None:
    rec, _ = out_and_back([1, 5])  # forward right, backward left
    plain = Recording(t=rec.t, x=rec.x + 0.3 * (rec.x - 5), y=rec.y, bounds=rec.bounds)  # a bit more sideways
    four = SegmentSettings(directions=("right", "forward", "left", "backward"))
    assert [s.label for s in segment(plain, four)] == ["right", "left"]


def test_small_wobbles_are_not_movements() -> None:
    rec, _ = out_and_back([0, 4])
    wobble = 0.2 * np.sin(np.arange(len(rec.t)) / 7)
    noisy = Recording(t=rec.t, x=rec.x + wobble, y=rec.y, bounds=rec.bounds, instruction=rec.instruction)
    assert [s.label for s in segment(noisy)] == ["right", "left"]


def test_bad_segment_settings_are_named() -> None:
    rec, _ = out_and_back([0])
    with pytest.raises(InvalidInput) as exc:
        segment(rec, SegmentSettings(min_prominence=1.5, directions=("up",)))
    assert pointers(exc) == ["/segment/min_prominence", "/segment/directions"]
    assert "('up' is not one)" in str(exc.value)


def test_demonstrations_group_valid_trajectories_by_label() -> None:
    rec, labels = out_and_back([2, 2, 6, 0, 2])
    demos = demonstrations(rec, discretise_settings=EXACT)
    assert {k: len(v) for k, v in demos.by_label.items()} == {"forward": 3, "backward": 1, "right": 1}
    mdp = grid_mdp(width=10, height=10, velocity=True, gamma=0.9)
    for trajectories in demos.by_label.values():
        validate_trajectories(mdp, trajectories)
    # A forward movement goes up three cells and back: its actions are forward then backward.
    first = demos.by_label["forward"][0]
    assert set(first.actions.tolist()) == {2, 6}
    assert [s.label for s in demos.segments] == labels


def test_a_session_without_movements_is_rejected() -> None:
    t = np.arange(200) / 100
    still = Recording.build(t=t, x=5.2 + 1.0 * (t > 1), y=np.full(200, 5.5), bounds=PLATE)
    with pytest.raises(InvalidInput) as exc:
        demonstrations(still, discretise_settings=EXACT)
    assert pointers(exc) == ["/samples"] and "no out-and-back movement" in str(exc.value)
