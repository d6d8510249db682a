"""Reward maps, correlation matrices and COP paths as PNG images, for the ``?format=png`` downloads.

matplotlib (Agg) is imported inside the functions, so importing this module costs the API process nothing
until a picture is asked for; torch is never imported. Figures are plain `matplotlib.figure.Figure`
objects (no pyplot global state, safe in threads) written at exactly their figure size, without
metadata, so the same data gives the same bytes and a pixel size known in advance:

- heatmap: ``cols × 3.0 + 1.0`` by ``rows × (map + 0.75) + 0.75`` inches, where the panels sit in
  ``rows = max(1, round(sqrt(channels / 2)))`` rows of ``cols = ceil(channels / rows)`` and
  ``map = clip(round_to_quarter(2.5 × height / width), 1.0, 5.0)``; see `heatmap_pixel_size`.
  At dpi 100 a square single map is 400 × 400 px and a square velocity grid (8 channels, 2 × 4 panels)
  is 1300 × 725 px.
- matrix: ``3.5 + 0.75 n`` by ``2.5 + 0.75 n`` inches for n labels; see `matrix_pixel_size`.
  At dpi 100 a 3 × 3 matrix is 575 × 475 px.
"""

from __future__ import annotations

import io
import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from metairl_engine.grids import DIRECTION_NAMES
from metairl_engine.mdp import Layout
from service.files.exports import as_values, check_layout, grid_coordinates

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

PANEL_WIDTH_IN = 3.0
"""Width of one channel panel (map, tick labels and margins), inches."""
PANEL_FRAME_IN = 0.75
"""Height a panel needs above and below its map (panel title, x tick labels), inches."""
MAP_WIDTH_IN = 2.5
"""Nominal width of the map inside a panel; its height follows the grid's aspect ratio, inches."""
COLORBAR_IN = 1.0
"""Width of the shared colour bar column, inches."""
TITLE_IN = 0.75
"""Height of the figure title strip, inches."""
MATRIX_CELL_IN = 0.75
"""Side of one correlation-matrix cell, inches."""
MIN_DPI, MAX_DPI = 20, 400
"""Accepted resolutions (dots per inch)."""
MAX_LABEL = 20
"""Matrix labels longer than this are shortened with an ellipsis."""
TITLE_CHARS_PER_IN = 8.5
"""Characters of a figure title (12 pt DejaVu Sans, about 0.1 inch a character) that fit an inch of figure
width with its margins: a longer title is wrapped, not cut off at the picture's edge."""
TITLE_LINES = 2
"""Lines a wrapped title may take; the rest is shortened with an ellipsis."""


def panel_grid(channels: int) -> tuple[int, int]:
    """(rows, cols) of the channel panels: one row up to 3 channels, 2 × 4 for a velocity grid's 8."""
    rows = max(1, round(math.sqrt(channels / 2)))
    return rows, math.ceil(channels / rows)


def heatmap_pixel_size(*, layout: Layout, dpi: int = 100) -> tuple[int, int]:
    """(width, height) in pixels of `heatmap_png` for this layout and resolution."""
    width_in, height_in = _heatmap_inches(layout)
    return int(width_in * dpi), int(height_in * dpi)


def matrix_pixel_size(*, n: int, dpi: int = 100) -> tuple[int, int]:
    """(width, height) in pixels of `matrix_png` for an n × n matrix and this resolution."""
    width_in, height_in = _matrix_inches(n)
    return int(width_in * dpi), int(height_in * dpi)


@dataclass(frozen=True)
class Scale:
    """A fixed colour scale for a quantity of known levels: a colour then means one level on every map."""

    low: float
    high: float
    ticks: Mapping[float, str] = field(default_factory=dict)
    """Colour-bar ticks at these values, labelled (none: matplotlib's)."""


def heatmap_png(
    values: np.ndarray,
    *,
    layout: Layout,
    title: str,
    channel_names: Sequence[str] | None = None,
    trajectories: Sequence[np.ndarray] | None = None,
    colorbar_label: str = "reward",
    scale: Scale | None = None,
    dpi: int = 100,
) -> bytes:
    """PNG of a per-state quantity drawn as one map per channel on a shared colour scale (see `heatmap_figure`)."""
    return _png(
        heatmap_figure(
            values,
            layout=layout,
            title=title,
            channel_names=channel_names,
            trajectories=trajectories,
            colorbar_label=colorbar_label,
            scale=scale,
            dpi=dpi,
        )
    )


def heatmap_figure(
    values: np.ndarray,
    *,
    layout: Layout,
    title: str,
    channel_names: Sequence[str] | None = None,
    trajectories: Sequence[np.ndarray] | None = None,
    colorbar_label: str = "reward",
    scale: Scale | None = None,
    dpi: int = 100,
) -> Figure:
    """The heatmap figure: a panel per channel, origin bottom-left (+y up = forward), one colour bar, spanning
    the values or, given a `Scale`, fixed with its named ticks.

    Panel titles default to the velocity directions of `metairl_engine.grids.DIRECTION_NAMES` when there
    are 8 channels, "channel k" otherwise, and none for a single channel. Each trajectory (state indices)
    is drawn as a line with a circle at its first state and a cross at its last; with several channels
    the move into a state is drawn in that state's panel (on a velocity grid: the panel of the direction
    moved), so a trajectory that turns continues in another panel.
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    arr = as_values(values)
    if arr.ndim != 1:
        raise ValueError(f"a heatmap needs a vector of shape (n_states,), got {arr.shape}")
    check_layout(layout, arr.shape[0])
    _check_dpi(dpi)
    names = _channel_names(layout.channels, channel_names)
    maps = arr.reshape(layout.channels, layout.height, layout.width)
    low, high = (scale.low, scale.high) if scale else (float(arr.min()), float(arr.max()))
    if low == high:
        low, high = low - 0.5, high + 0.5

    rows, cols = panel_grid(layout.channels)
    fig = Figure(figsize=_heatmap_inches(layout), dpi=dpi, layout="constrained")
    grid = fig.subplots(rows, cols, squeeze=False)
    panels: list[Axes] = list(grid.ravel()[: layout.channels])
    for spare in grid.ravel()[layout.channels :]:
        spare.remove()
    extent = (-0.5, layout.width - 0.5, -0.5, layout.height - 0.5)
    colours = _colours(scale, low, high)
    for channel, ax in enumerate(panels):
        image = ax.imshow(maps[channel], origin="lower", extent=extent, **colours)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        if names[channel]:
            ax.set_title(names[channel], fontsize="medium")
        if channel % cols == 0:
            ax.set_ylabel("y")
        if channel + cols >= layout.channels:
            ax.set_xlabel("x")
    bar = fig.colorbar(image, ax=panels, label=colorbar_label, shrink=0.9)
    if scale and scale.ticks:
        bar.set_ticks(list(scale.ticks), labels=list(scale.ticks.values()))
    _suptitle(fig, title)
    if trajectories:
        _overlay(fig, panels, trajectories, layout)
    return fig


def _colours(scale: Scale | None, low: float, high: float) -> dict[str, Any]:
    """``imshow``'s colour arguments: viridis from low to high, or for a `Scale` with named levels one
    viridis colour per level in blocks (each level's colour out to halfway to its neighbours), so a colour
    bar of a few categories shows those categories, not a continuum between them."""
    if not (scale and scale.ticks):
        return {"cmap": "viridis", "vmin": low, "vmax": high}
    from matplotlib import colormaps
    from matplotlib.colors import BoundaryNorm, ListedColormap

    levels = np.array(sorted(scale.ticks), dtype=np.float64)
    span = max(scale.high - scale.low, 1e-12)
    cmap = ListedColormap(colormaps["viridis"]((levels - scale.low) / span))
    gaps = np.diff(levels) if len(levels) > 1 else np.ones(1)
    edges = [levels[0] - gaps[0] / 2, *(levels[1:] - gaps / 2), levels[-1] + gaps[-1] / 2]
    return {"cmap": cmap, "norm": BoundaryNorm(edges, cmap.N)}


def matrix_png(
    matrix: np.ndarray,
    *,
    labels: Sequence[str],
    title: str,
    colorbar_label: str = "Pearson r",
    dpi: int = 100,
) -> bytes:
    """PNG of an annotated correlation matrix (see `matrix_figure`)."""
    return _png(matrix_figure(matrix, labels=labels, title=title, colorbar_label=colorbar_label, dpi=dpi))


def matrix_figure(
    matrix: np.ndarray,
    *,
    labels: Sequence[str],
    title: str,
    colorbar_label: str = "Pearson r",
    dpi: int = 100,
) -> Figure:
    """The matrix figure: diverging colours fixed to −1..1, each value printed in its cell, NaN as "n/a"."""
    import matplotlib
    from matplotlib.figure import Figure

    m = np.asarray(matrix, dtype=np.float64)
    n = len(labels)
    if m.shape != (n, n) or n == 0:
        raise ValueError(f"matrix must be square with one row per label ({n}), got shape {m.shape}")
    if np.isinf(m).any():
        raise ValueError("matrix must not hold infinities (NaN marks an undefined correlation)")
    _check_dpi(dpi)
    short = [label if len(label) <= MAX_LABEL else label[: MAX_LABEL - 1] + "…" for label in labels]

    fig = Figure(figsize=_matrix_inches(n), dpi=dpi, layout="constrained")
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="0.85")
    image = ax.imshow(np.ma.masked_invalid(m), cmap=cmap, vmin=-1.0, vmax=1.0)
    for (row, col), value in np.ndenumerate(m):
        text = "n/a" if np.isnan(value) else f"{value:.2f}"
        colour = "white" if abs(value) > 0.6 else "black"
        ax.text(col, row, text, ha="center", va="center", color=colour, fontsize="small")
    ax.set_xticks(range(n), short, rotation=45, ha="right", rotation_mode="anchor")
    ax.set_yticks(range(n), short)
    fig.colorbar(image, ax=ax, label=colorbar_label)
    _suptitle(fig, title)
    return fig


def _suptitle(fig: Figure, title: str) -> None:
    """The figure's title, wrapped to its width (`TITLE_CHARS_PER_IN`, at most `TITLE_LINES` lines): a task
    and demonstrator name of any length stays inside the picture, whose size does not change."""
    width = max(10, int(fig.get_figwidth() * TITLE_CHARS_PER_IN))
    fig.suptitle(textwrap.fill(title, width=width, max_lines=TITLE_LINES, placeholder=" …"))


def _heatmap_inches(layout: Layout) -> tuple[float, float]:
    """Figure size in inches; every term is a multiple of 1/4 so inches × dpi is exact."""
    rows, cols = panel_grid(layout.channels)
    map_height = min(5.0, max(1.0, round(4 * MAP_WIDTH_IN * layout.height / layout.width) / 4))
    return cols * PANEL_WIDTH_IN + COLORBAR_IN, rows * (map_height + PANEL_FRAME_IN) + TITLE_IN


def _matrix_inches(n: int) -> tuple[float, float]:
    """Figure size in inches of an n × n matrix (labels, cells, colour bar, title)."""
    return 3.5 + MATRIX_CELL_IN * n, 2.5 + MATRIX_CELL_IN * n


def _check_dpi(dpi: int) -> None:
    """Refuse resolutions that would give unreadable or needlessly huge images."""
    if not (isinstance(dpi, int) and MIN_DPI <= dpi <= MAX_DPI):
        raise ValueError(f"dpi must be an integer in {MIN_DPI}..{MAX_DPI}, got {dpi!r}")


def _channel_names(channels: int, given: Sequence[str] | None) -> list[str]:
    """Panel titles: the caller's, else direction names for 8 channels, "channel k", or none for one map."""
    if given is not None:
        if len(given) != channels:
            raise ValueError(f"channel_names has {len(given)} names for {channels} channels")
        return list(given)
    if channels == len(DIRECTION_NAMES):
        return list(DIRECTION_NAMES)
    return [""] if channels == 1 else [f"channel {k}" for k in range(channels)]


def _overlay(fig: Figure, panels: list[Axes], trajectories: Sequence[np.ndarray], layout: Layout) -> None:
    """Draw each trajectory's moves in the panel of the state moved into, with start and end markers."""
    import matplotlib
    from matplotlib.lines import Line2D
    from matplotlib.patheffects import withStroke

    colours = matplotlib.colormaps["Set1"]
    outline = [withStroke(linewidth=3.5, foreground="white")]
    for i, trajectory in enumerate(trajectories):
        states = np.asarray(trajectory)
        if states.ndim != 1 or states.size == 0:
            raise ValueError(f"trajectory {i} must be a non-empty 1-D array of states, got {states.shape}")
        x, y, channel = grid_coordinates(states, layout)
        colour = colours(i % colours.N)
        for c in np.unique(channel[1:]):
            xs, ys = _polyline(x, y, keep=channel[1:] == c)
            panels[c].plot(xs, ys, color=colour, linewidth=2.0, path_effects=outline)
        for at, marker in ((0, "o"), (-1, "X")):
            panels[channel[at]].plot(
                x[at], y[at], marker=marker, color=colour, markeredgecolor="white", markersize=9
            )
    markers = [
        Line2D([], [], linestyle="", marker=m, color="0.3", markeredgecolor="white", markersize=8, label=lab)
        for m, lab in (("o", "start"), ("X", "end"))
    ]
    fig.legend(handles=markers, loc="outside lower center", ncols=2, fontsize="small")


def _polyline(x: np.ndarray, y: np.ndarray, *, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points touched by the kept segments t → t+1 (``keep`` has n-1 flags), NaN between separate runs."""
    n = len(x)
    segment = np.zeros(n, dtype=bool)
    segment[:-1] = keep
    used = segment | np.concatenate([[False], keep])
    points = np.full((n, 2, 2), np.nan)
    points[:, 0, 0], points[:, 0, 1] = x, y
    chosen = points.reshape(2 * n, 2)[np.column_stack([used, used & ~segment]).ravel()][:-1]
    return chosen[:, 0], chosen[:, 1]


SWAY_INCHES = (5.0, 5.0)
"""Size of `sway_png`'s figure: 500 × 500 px at dpi 100."""


def sway_png(
    x: np.ndarray,
    y: np.ndarray,
    outline: np.ndarray,
    *,
    units: str | None,
    title: str,
    dpi: int = 100,
) -> bytes:
    """A COP path (x right, y forward) with its 95 % prediction ellipse ``outline`` (K, 2), equal axes."""
    from matplotlib.figure import Figure

    _check_dpi(dpi)
    fig = Figure(figsize=SWAY_INCHES, dpi=dpi)
    ax = fig.add_axes((0.17, 0.12, 0.78, 0.78))
    ax.plot(x, y, color="#1f77b4", linewidth=0.6, label="COP path")
    ax.plot(outline[:, 0], outline[:, 1], color="#d62728", linewidth=1.5, label="95 % prediction ellipse")
    ax.set_aspect("equal", adjustable="datalim")
    unit = f" ({units})" if units else ""
    ax.set_xlabel(f"x, right{unit}")
    ax.set_ylabel(f"y, forward{unit}")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    return _png(fig)


def _png(fig: Figure) -> bytes:
    """Render at exactly the figure's size with the Agg canvas; no 'Software' stamp, so bytes are stable."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    buf = io.BytesIO()
    FigureCanvasAgg(fig).print_png(buf, metadata={"Software": None})
    return buf.getvalue()
