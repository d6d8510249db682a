"""Centre of pressure (COP) from a force plate's forces and moments (docs/motion.md, "Force-plate files").

numpy only. A plate measures the force F and the moment M about its measurement origin; a vertical-ish load
applied at a point r of the surface gives M = r × F, so the COP is r_x = (r_z F_x − M_y) / F_z and
r_y = (M_x + r_z F_y) / F_z, with r_z the surface's height above the origin along the plate's z axis. That
holds in any right-handed frame as long as F and M describe the same wrench (both as applied to the plate, or
both as the reaction), so the sign of F_z cancels; what a file must declare is where its x and y axes point
(`PlateAxes`) and how deep the origin lies below the surface. Samples whose |F_z| is too small to locate a
COP (stepping on or off the plate) are cut away by `loaded_span`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from metairl_engine.errors import Issue, check

Direction = Literal["right", "left", "forward", "backward"]
PATIENT_VECTORS: dict[str, tuple[int, int]] = {
    "right": (1, 0),
    "left": (-1, 0),
    "forward": (0, 1),
    "backward": (0, -1),
}
"""Each direction a plate axis may point to, in the recording's own frame (+x right, +y forward)."""
LENGTH_UNITS: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001}
"""Metres per unit, for the position (C3D) or moment (CSV) lengths a file may use; recordings store metres."""
UNIT_NAMES: dict[str, tuple[str, ...]] = {
    "m": ("m", "meter", "metre", "meters", "metres"),
    "cm": ("cm", "centimeter", "centimetre", "centimeters", "centimetres"),
    "mm": ("mm", "millimeter", "millimetre", "millimeters", "millimetres"),
}
"""Spellings of each `LENGTH_UNITS` key that `length_unit` reads."""
NEVER_LOADED = "never loaded"
"""How the issue of a plate with no loaded sample begins."""
MIN_FZ = 20.0
"""Default least |F_z| (N) of a loaded sample: the usual contact threshold of force-plate software."""


@dataclass(frozen=True)
class PlateAxes:
    """Where the plate's +x and +y axes point, as the patient's directions; +z completes a right-handed frame.

    The default (x right, y forward, so z up) is the recording's own frame. An AMTI plate in its own frame
    (z down) placed with +y forward has x = ``left``.
    """

    x: Direction = "right"
    y: Direction = "forward"

    def issues(self, pointer: str = "/plate/axes") -> list[Issue]:
        """An issue unless x and y point to perpendicular directions."""
        (ax, ay), (bx, by) = PATIENT_VECTORS[self.x], PATIENT_VECTORS[self.y]
        if ax * bx + ay * by == 0:
            return []
        return [Issue(f"{pointer}/y", f"must be perpendicular to x = {self.x!r}, got {self.y!r}")]

    @property
    def z_up(self) -> bool:
        """Whether +z points up (x × y is up), which decides on which side of the origin the surface lies."""
        (ax, ay), (bx, by) = PATIENT_VECTORS[self.x], PATIENT_VECTORS[self.y]
        return ax * by - ay * bx > 0

    def to_patient(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) plate coordinates as (right, forward) coordinates of the recording."""
        basis = np.array([PATIENT_VECTORS[self.x], PATIENT_VECTORS[self.y]], dtype=np.float64)
        return np.asarray(xy, dtype=np.float64) @ basis


def wrench_cop(force: np.ndarray, moment: np.ndarray, *, z_up: bool, origin_depth: float = 0.0) -> np.ndarray:
    """(N, 2) COP on the plate surface in plate axes from force and moment (N, 3) about the measurement origin,
    which lies `origin_depth` below the surface (in the moments' length unit); NaN where F_z is 0."""
    f, m = np.asarray(force, dtype=np.float64), np.asarray(moment, dtype=np.float64)
    rz = origin_depth if z_up else -origin_depth
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (rz * f[:, 0] - m[:, 1]) / f[:, 2]
        y = (m[:, 0] + rz * f[:, 1]) / f[:, 2]
    return np.stack([x, y], axis=1)


def loaded_span(fz: np.ndarray, min_fz: float = MIN_FZ) -> slice:
    """The samples from the first to the last with |F_z| ≥ `min_fz`, so stepping on and off the plate is cut
    away; `InvalidInput` if no sample is loaded, or one between loaded samples is not (its COP is undefined)."""
    size = np.abs(np.nan_to_num(np.asarray(fz, dtype=np.float64)))
    loaded = size >= min_fz
    found = np.flatnonzero(loaded)
    if found.size == 0:
        check(
            [
                Issue(
                    "/samples",
                    f"{NEVER_LOADED}: no sample has |Fz| ≥ {min_fz:g} N (the largest is {size.max(initial=0.0):.3g} N): the plate "
                    "was never loaded, or the force channels are not the plate's",
                )
            ]
        )
    span = slice(int(found[0]), int(found[-1]) + 1)
    gaps = np.flatnonzero(~loaded[span]) + span.start
    if gaps.size:
        k = int(gaps[0])
        check(
            [
                Issue(
                    f"/samples/{k}/fz",
                    f"|Fz| = {size[k]:.3g} N is below min_fz = {min_fz:g} N between loaded samples ({gaps.size} "
                    "such samples): the COP is undefined there; upload the loaded stretches separately, or lower "
                    "min_fz",
                )
            ]
        )
    return span


def length_unit(name: str) -> str | None:
    """The `LENGTH_UNITS` key a file's unit string means, read leniently: any case, blanks and NUL padding
    ignored, a spelling of `UNIT_NAMES` or a cut-off one of at least three letters (``mete`` is ``m``, as C3D
    writers truncate to the parameter's width); None if it names no length unit or more than one."""
    text = name.replace("\0", "").strip().lower()
    if not text:
        return None
    exact = [unit for unit, spellings in UNIT_NAMES.items() if text in spellings]
    if exact:
        return exact[0]
    cut = {
        unit
        for unit, spellings in UNIT_NAMES.items()
        for s in spellings
        if len(text) >= 3 and s.startswith(text)
    }
    return cut.pop() if len(cut) == 1 else None


def loaded_stretches(fz: np.ndarray, min_fz: float = MIN_FZ) -> list[slice]:
    """The maximal runs of consecutive samples with |F_z| ≥ `min_fz`, in time order (empty if none is loaded)."""
    loaded = np.abs(np.nan_to_num(np.asarray(fz, dtype=np.float64))) >= min_fz
    edges = np.flatnonzero(np.diff(np.r_[0, loaded.astype(np.int8), 0]))
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]
