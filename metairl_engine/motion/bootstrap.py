"""Percentile-bootstrap intervals over repetitions, drawn by ``scipy.stats.bootstrap`` (the kinematic readout,
the learned readout's agreement and the sway measures use it).

numpy at import; scipy is imported when an interval is drawn, so the API process loads it only then.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np


def percentile_interval(
    samples: Sequence[np.ndarray],
    statistic: Callable[..., np.ndarray],
    *,
    n_resamples: int,
    rng: np.random.Generator,
    confidence: float = 0.95,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The ``confidence`` percentile interval (low, high) of ``statistic(*samples, axis=-1)``, each sample's
    repetitions (its last axis) resampled independently of the others'. A sample of one repetition has
    nothing to resample and is held as it is; None when no sample has two."""
    from scipy import stats

    moving = [i for i, s in enumerate(samples) if s.shape[-1] > 1]
    if not moving:
        return None

    def with_held(*resampled: np.ndarray, axis: int = -1) -> np.ndarray:
        """``statistic`` of the resampled samples with the held ones put back in their places."""
        extra = resampled[0].ndim - samples[moving[0]].ndim  # the resample axis scipy adds
        full = [s.reshape(s.shape[:-1] + (1,) * extra + s.shape[-1:]) for s in samples]
        for i, r in zip(moving, resampled, strict=True):
            full[i] = r
        return statistic(*full, axis=axis)

    ci = stats.bootstrap(
        [samples[i] for i in moving],
        with_held,
        axis=-1,
        vectorized=True,
        paired=False,
        confidence_level=confidence,
        n_resamples=n_resamples,
        method="percentile",
        rng=rng,
    ).confidence_interval
    return np.asarray(ci.low, dtype=np.float64), np.asarray(ci.high, dtype=np.float64)
