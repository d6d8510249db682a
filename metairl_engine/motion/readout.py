"""What a velocity-grid baseline can say about a patient's inherent preference (numpy only).

Out-and-back demonstrations of instruction k cover only the ray from the rest position along k. Along that
ray, "move outward, then back" (the task) and any preference that changes with the distance from the rest
position (the patient's) predict the same choices, so the *radial* profile of a learned baseline is not
identified by such data: it takes whatever the fit's prior gives it. What the data do constrain is how the
baseline differs between places at the same distance: between directions (the weak side against the
others) and across each ray (which way paths bend). `ring_centred` keeps only that part: it subtracts, from
every state's value, the mean over the given states at the same distance from the origin cell.
docs/motion.md (identifiability) and benchmarks/MOTION.md measure it.
"""

from __future__ import annotations

import numpy as np

from metairl_engine.grids import velocity_coords


def ring_centred(
    reward: np.ndarray,
    *,
    width: int,
    height: int,
    states: np.ndarray,
    origin: tuple[float, float] | None = None,
    ring: float = 1.0,
) -> np.ndarray:
    """``reward`` on ``states`` (velocity-grid state indices, (M,)) minus its mean over the states in the same
    ring: distance of the state's cell from ``origin`` (cell coordinates, default the grid centre) rounded
    to multiples of ``ring`` cells. Returns (M,) float64, in the order of ``states``."""
    x, y, _ = velocity_coords(np.asarray(states), width=width, height=height)
    ox, oy = ((width - 1) / 2, (height - 1) / 2) if origin is None else origin
    bins = np.round(np.hypot(x - ox, y - oy) / ring).astype(np.int64)
    values = np.asarray(reward, dtype=np.float64)[np.asarray(states)]
    sums = np.bincount(bins, weights=values)
    counts = np.bincount(bins)
    return np.asarray(values - (sums / np.maximum(counts, 1))[bins])


BASELINE_CAVEAT = (
    "Out-and-back movements identify how the baseline differs between directions and across each path, not "
    "how it changes with distance from the centre: moving out to the instructed distance is shared by every "
    "task and can be learned as part of the baseline. On synthetic patients whose paths are only bent by "
    "their preference (not planned), the baseline did not correlate with that preference. Read reach, "
    "the weak side and session differences from the kinematic readout; read the baseline as a preference "
    "only where its between-direction differences agree with it."
)
"""What the API should say next to a baseline learned from recordings (docs/api.md, "Motion readout"); see docs/motion.md."""
