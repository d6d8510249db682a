"""PNG reward maps and correlation matrices: pixel sizes, panels, shared scale, orientation and overlays."""

import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.lines import Line2D
from PIL import Image

from metairl_engine.evidence import NEXT_TO_VISITED, VISITED
from metairl_engine.grids import DIRECTION_NAMES, velocity_state
from metairl_engine.mdp import Layout
from service.files.images import (
    Scale,
    heatmap_figure,
    heatmap_pixel_size,
    heatmap_png,
    matrix_figure,
    matrix_pixel_size,
    matrix_png,
    panel_grid,
)

ROOT = Path(__file__).resolve().parents[2]
VELOCITY = Layout(width=6, height=6, channels=8)


def decoded_size(png: bytes) -> tuple[int, int]:
    image = Image.open(io.BytesIO(png))
    assert image.format == "PNG"
    image.load()
    return image.size


def points(line: Line2D) -> list[list[float]]:
    return np.asarray(line.get_xydata(), dtype=float).tolist()


def test_importing_render_imports_neither_matplotlib_nor_torch() -> None:
    code = "import sys, service.files.images; print(sorted({'matplotlib', 'torch'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_panel_grid_shapes() -> None:
    assert [panel_grid(c) for c in (1, 2, 3, 5, 8)] == [(1, 1), (1, 2), (1, 3), (2, 3), (2, 4)]


def test_documented_pixel_sizes() -> None:
    assert heatmap_pixel_size(layout=Layout(width=10, height=10)) == (400, 400)
    assert heatmap_pixel_size(layout=Layout(width=100, height=100, channels=8)) == (1300, 725)
    assert heatmap_pixel_size(layout=Layout(width=10, height=10), dpi=200) == (800, 800)
    assert matrix_pixel_size(n=3) == (575, 475)


@pytest.mark.parametrize(
    ("layout", "dpi"),
    [(Layout(width=5, height=4), 100), (Layout(width=40, height=10), 72), (VELOCITY, 50)],
)
def test_heatmap_png_decodes_at_the_documented_size(layout: Layout, dpi: int) -> None:
    n = layout.width * layout.height * layout.channels
    png = heatmap_png(np.arange(n, dtype=np.float32), layout=layout, title="task t — demonstrator d", dpi=dpi)
    assert decoded_size(png) == heatmap_pixel_size(layout=layout, dpi=dpi)


def test_velocity_grid_has_eight_direction_panels_and_one_shared_colour_bar() -> None:
    values = np.random.default_rng(0).normal(size=288).astype(np.float32)
    fig = heatmap_figure(values, layout=VELOCITY, title="task forward — demonstrator patient 3")
    assert len(fig.axes) == 8 + 1
    panels = [ax for ax in fig.axes if ax.images]
    assert [ax.get_title() for ax in panels] == list(DIRECTION_NAMES)
    assert {ax.images[0].get_clim() for ax in panels} == {(float(values.min()), float(values.max()))}
    assert fig.get_suptitle() == "task forward — demonstrator patient 3"
    maps = values.reshape(8, 6, 6)
    for channel, ax in enumerate(panels):
        assert np.array_equal(np.asarray(ax.images[0].get_array()), maps[channel])
        assert ax.images[0].origin == "lower"


def test_other_channel_counts_get_numbered_or_given_titles() -> None:
    layout = Layout(width=2, height=3, channels=3)
    fig = heatmap_figure(np.zeros(18), layout=layout, title="t")
    assert len(fig.axes) == 3 + 1
    assert [ax.get_title() for ax in fig.axes[:3]] == ["channel 0", "channel 1", "channel 2"]
    fig = heatmap_figure(np.zeros(18), layout=layout, title="t", channel_names=["a", "b", "c"])
    assert [ax.get_title() for ax in fig.axes[:3]] == ["a", "b", "c"]
    assert len(heatmap_figure(np.zeros(6), layout=Layout(width=2, height=3), title="t").axes) == 2


def test_the_first_state_is_drawn_bottom_left() -> None:
    """Render a 2 × 2 map and read back the pixel colours at the cell centres (y must point up)."""
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = heatmap_figure(np.array([0.0, 0.0, 0.0, 1.0]), layout=Layout(width=2, height=2), title="t")
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    pixels = np.asarray(canvas.buffer_rgba())[..., :3].astype(float) / 255
    ax = fig.axes[0]

    def colour_at(x: float, y: float) -> np.ndarray:
        col, row = ax.transData.transform((x, y))
        return pixels[pixels.shape[0] - 1 - round(row), round(col)]

    low, high = np.array(colormaps["viridis"](0.0)[:3]), np.array(colormaps["viridis"](1.0)[:3])
    assert np.allclose(colour_at(0, 0), low, atol=0.02)
    assert np.allclose(colour_at(1, 0), low, atol=0.02)
    assert np.allclose(colour_at(1, 1), high, atol=0.02)


def test_a_fixed_scale_draws_each_level_in_its_own_colour_whatever_levels_one_map_holds() -> None:
    from matplotlib import colormaps
    from matplotlib.image import AxesImage

    from service.results.downloads import FIXED_SCALES

    evidence = FIXED_SCALES["evidence"]
    assert set(evidence.ticks) == {0.0, NEXT_TO_VISITED, VISITED}  # the engine's levels, each named
    for values in (np.full(4, VISITED), np.array([NEXT_TO_VISITED, VISITED] * 2)):
        fig = heatmap_figure(
            values, layout=Layout(width=2, height=2), title="t", colorbar_label="evidence", scale=evidence
        )
        image = next(a for a in fig.axes[0].get_children() if isinstance(a, AxesImage))
        for level in evidence.ticks:  # viridis at the level on the fixed scale, not on the map's own range
            drawn = image.cmap(image.norm(np.array([level])))[0]
            assert np.allclose(drawn, colormaps["viridis"](level)), level
        assert image.cmap.N == 3  # one block per level on the colour bar, not a continuum between them
        bar = fig.axes[-1]
        assert [t.get_text() for t in bar.get_yticklabels()] == ["elsewhere", "next to a visit", "visited"]
    unscaled = heatmap_figure(np.array([0.5, 1.0] * 2), layout=Layout(width=2, height=2), title="t")
    image = next(a for a in unscaled.axes[0].get_children() if isinstance(a, AxesImage))
    assert (image.norm.vmin, image.norm.vmax) == (0.5, 1.0)
    assert Scale(0.0, 1.0).ticks == {}


def test_trajectories_on_a_single_map_are_lines_with_start_and_end_markers() -> None:
    layout = Layout(width=5, height=4)
    walk, back = np.array([0, 1, 6, 11, 12]), np.array([19, 18])
    fig = heatmap_figure(np.zeros(20), layout=layout, title="t", trajectories=[walk, back])
    lines = fig.axes[0].lines
    assert len(lines) == 2 * 3
    path = [line for line in lines if line.get_marker() in ("None", "", None)]
    assert [points(line) for line in path] == [[[0, 0], [1, 0], [1, 1], [1, 2], [2, 2]], [[4, 3], [3, 3]]]
    markers = [(line.get_marker(), points(line)) for line in lines if line not in path]
    assert markers == [("o", [[0, 0]]), ("X", [[2, 2]]), ("o", [[4, 3]]), ("X", [[3, 3]])]
    png = heatmap_png(np.zeros(20), layout=layout, title="t", trajectories=[walk])
    assert decoded_size(png) == heatmap_pixel_size(layout=layout) == (400, 350)


def test_velocity_trajectory_moves_are_drawn_in_the_panel_of_their_direction() -> None:
    right = [velocity_state(x, 1, 0, width=6, height=6) for x in range(1, 4)]
    forward = [velocity_state(3, y, 2, width=6, height=6) for y in range(2, 5)]
    fig = heatmap_figure(np.zeros(288), layout=VELOCITY, title="t", trajectories=[np.array(right + forward)])
    panels = fig.axes[:8]
    assert [len(ax.lines) for ax in panels] == [2, 0, 2, 0, 0, 0, 0, 0]
    east, north = panels[0].lines[0], panels[2].lines[0]
    assert points(east) == [[1, 1], [2, 1], [3, 1]]
    assert points(north) == [[3, 1], [3, 2], [3, 3], [3, 4]]
    assert (panels[0].lines[1].get_marker(), panels[2].lines[1].get_marker()) == ("o", "X")


@pytest.mark.parametrize(
    "kwargs",
    [
        {"values": np.zeros(19)},
        {"values": np.zeros((20, 2))},
        {"values": np.full(20, np.nan)},
        {"trajectories": [np.array([0, 20])]},
        {"trajectories": [np.array([], dtype=int)]},
        {"channel_names": ["a", "b"]},
        {"dpi": 5000},
    ],
)
def test_heatmap_refuses_bad_input(kwargs: dict[str, object]) -> None:
    args: dict = {"values": np.zeros(20), "layout": Layout(width=5, height=4), "title": "t"} | kwargs
    with pytest.raises(ValueError):
        heatmap_figure(**args)


def test_png_bytes_are_stable_for_the_same_data() -> None:
    layout = Layout(width=4, height=3)
    values = np.linspace(-1, 1, 12)
    first = heatmap_png(values, layout=layout, title="t", dpi=40)
    assert first == heatmap_png(values, layout=layout, title="t", dpi=40)
    assert first != heatmap_png(values[::-1], layout=layout, title="t", dpi=40)


def test_correlation_matrix_is_annotated_on_a_fixed_diverging_scale() -> None:
    matrix = np.array([[1.0, 0.5, np.nan], [0.5, 1.0, -0.8], [np.nan, -0.8, 1.0]])
    labels = ["baseline", "forward", "a very long task name that goes on"]
    fig = matrix_figure(matrix, labels=labels, title="job_1")
    assert len(fig.axes) == 2
    ax = fig.axes[0]
    assert ax.images[0].get_clim() == (-1.0, 1.0)
    assert ax.images[0].get_cmap().name.startswith("RdBu_r")
    assert [t.get_text() for t in ax.texts] == [
        "1.00",
        "0.50",
        "n/a",
        "0.50",
        "1.00",
        "-0.80",
        "n/a",
        "-0.80",
        "1.00",
    ]
    assert [t.get_text() for t in ax.get_xticklabels()][:2] == labels[:2]
    assert len(ax.get_xticklabels()[2].get_text()) <= 20
    png = matrix_png(matrix, labels=labels, title="job_1")
    assert decoded_size(png) == matrix_pixel_size(n=3) == (575, 475)


def test_matrix_refuses_a_shape_that_does_not_match_the_labels() -> None:
    with pytest.raises(ValueError):
        matrix_figure(np.eye(3), labels=["a", "b"], title="t")


@pytest.mark.parametrize(
    "title",
    [
        "goal 91 — objectworld demonstrator (uncertainty)",
        "a task named at great length — a demonstrator whose name runs on and on and on (evidence)",
    ],
)
def test_a_long_title_is_wrapped_inside_the_picture_and_its_size_stays(title: str) -> None:
    layout = Layout(width=12, height=12)
    fig = heatmap_figure(np.linspace(0, 1, 144), layout=layout, title=title)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    text = fig.get_suptitle()
    box = next(t for t in fig.texts if t.get_text() == text).get_window_extent(renderer)
    assert box.x0 >= 0 and box.x1 <= fig.bbox.width and box.y1 <= fig.bbox.height
    assert 1 < len(text.splitlines()) <= 2 and text.replace("\n", " ").split()[:3] == title.split()[:3]
    assert decoded_size(
        heatmap_png(np.linspace(0, 1, 144), layout=layout, title=title)
    ) == heatmap_pixel_size(layout=layout)
