"""Quiet-standing sway measures of a centre-of-pressure (COP) recording (docs/motion.md, "Quiet standing").

numpy and scipy only. `sway_measures` computes the classic time- and frequency-domain posturography
measures of Prieto et al. (1996), "Measures of postural steadiness: differences between healthy young and
elderly adults", IEEE Trans Biomed Eng 43(9):956-966, with the conventions of Duarte's BMClab notebooks
(github.com/BMClab/BMC: ``hyperellipsoid.py``, ``psd.py``) that the public balance data set of Santos &
Duarte (2016, PeerJ 4:e2648) used for its published ``COParea``, ``COPvelo`` and ``COPmfreq``:

- x and y are taken about their mean (``x̃ = x − mean(x)``); N samples at rate fs span T = N / fs, fs from the
  span of the times (`sampling_rate`);
- path length ``L = Σ √(Δx² + Δy²)``, mean velocity ``L / T`` (per axis ``Σ|Δx| / T``);
- mean distance ``mean √(x̃² + ỹ²)``; RMS per axis ``√mean x̃²``; range ``max − min``;
- 95 % prediction ellipse (Chew 1966; Schubert & Kirchner 2014): the region holding a new sample with
  probability 0.95 for bivariate normal samples, semi-axes ``√(λᵢ c)`` of the sample covariance's
  eigenvalues λᵢ with ``c = 2 (n+1)(n−1) / (n (n−2)) · F(0.95; 2, n−2)``, area ``π c √det(cov)``;
- sway area per second (Hufschmidt et al. 1980; Prieto's AREA-SW) ``Σ |x̃ᵢ ỹᵢ₊₁ − x̃ᵢ₊₁ ỹᵢ| / (2T)``;
- Welch spectra per axis (Hann window, segments of N/2 samples overlapping by N/4, nfft N/2, each segment's
  mean removed); an axis's mean frequency ``∫ f P df / ∫ P df`` (trapezoid rule), the two combined weighted
  by their total power ``Σ P``; the 95 % power frequency the lowest f below which 95 % of ``∫ P df`` lies;
  given with a caveat below `MIN_SPECTRAL_DURATION_S`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np

from metairl_engine.errors import Issue, check
from metairl_engine.motion.bootstrap import percentile_interval
from metairl_engine.motion.recording import sampling_rate

ELLIPSE_P = 0.95
POWER_FRACTION = 0.95
MIN_SWAY_SAMPLES = 8
"""Fewest samples the measures are computed on (Welch needs segments of at least four)."""
MIN_SPECTRAL_DURATION_S = 20.0
"""Shortest analysed stretch whose frequency measures come without a caveat. Segments of N/2 samples put the Welch bins 2/T apart:
0.1 Hz at 20 s, against quiet-standing mean frequencies of 0.1-0.5 Hz; 20 s is also the shortest test whose
spectral median frequency Vieira, Oliveira & Nadal (2009, Braz J Med Biol Res 42:665) found reliable."""
SPECTRAL = ("mean_frequency", "mean_frequency_x", "mean_frequency_y", "f95", "f95_x", "f95_y")
"""The measures taken from the Welch spectra."""
LENGTH_POWER: dict[str, int] = {
    "path_length": 1,
    "mean_velocity": 1,
    "mean_velocity_x": 1,
    "mean_velocity_y": 1,
    "mean_distance": 1,
    "rms": 1,
    "rms_x": 1,
    "rms_y": 1,
    "range_x": 1,
    "range_y": 1,
    "area95": 2,
    "ellipse_major": 1,
    "ellipse_minor": 1,
    "ellipse_angle": 0,
    "sway_area_per_second": 2,
    **dict.fromkeys(SPECTRAL, 0),
    "centre_x": 1,
    "centre_y": 1,
}
"""The power of the length unit each measure carries: a measure in unit u is ``value · k**power`` in a unit k
times smaller (areas by the square, lengths and velocities linearly, angles and frequencies unchanged)."""
NO_RATIO = frozenset({"ellipse_angle", "centre_x", "centre_y"})
"""Measures whose ratio means nothing (an angle, positions: their zero is arbitrary), so no quotient is given."""

METHODS: dict[str, str] = {
    "centring": "x and y taken about their mean over the analysed samples",
    "rate": "(N - 1) / (t_last - t_first) in float64 (times rounded on storage average out); the median "
    "interval's inverse where an interval exceeds 1.5 times the median (a gap: samples missing)",
    "duration": "N samples / rate (each sample stands for 1/rate)",
    "path_length": "sum of the distances between consecutive samples",
    "mean_velocity": "path length / duration (per axis: sum of |dx| or |dy| / duration); Prieto et al. 1996",
    "mean_distance": "mean distance from the mean COP; Prieto et al. 1996",
    "rms": "root mean square of the centred samples (population, 1/N)",
    "range": "max - min per axis",
    "area95": "95 % prediction ellipse of a new sample, F quantile: c = 2(n+1)(n-1)/(n(n-2)) F(0.95; 2, n-2), "
    "area = pi c sqrt(det cov), semi-axes sqrt(c lambda_i) of the sample covariance (1/(n-1)); Chew 1966, "
    "Schubert & Kirchner 2014, as in Santos & Duarte 2016. Duarte's hyperellipsoid.py omits (n+1)/n (area "
    "1/n smaller); chi-square ellipses (c = 5.991) are 1 - c/(2F(n+1)(n-1)/(n(n-2))) smaller",
    "ellipse_angle": "angle of the ellipse's major axis from +x towards +y, degrees in (-90, 90]",
    "sway_area_per_second": "sum |x_i y_(i+1) - x_(i+1) y_i| / (2 duration) on centred samples; Hufschmidt 1980, "
    "Prieto et al. 1996 (AREA-SW)",
    "spectra": "Welch per axis: Hann window, segments of N/2 samples, N/4 overlap, nfft N/2, each segment's "
    "mean removed, one-sided density (scipy.signal.welch)",
    "mean_frequency": "per axis int f P df / int P df (trapezoid rule, Duarte's psd.py); the two axes combined "
    "weighted by their total power sum P, as in Santos & Duarte 2016",
    "f95": "lowest frequency below which 95 % of int P df lies (cumulative trapezoid); combined: of Px + Py",
    "minimum_duration": f"frequency measures of under {MIN_SPECTRAL_DURATION_S:g} s analysed carry a caveat (Welch "
    "bins 2/T apart: 0.1 Hz at 20 s; Vieira et al. 2009)",
}
"""How each measure is computed, as the sway route reports it in ``methods``."""


@dataclass(frozen=True)
class SwayOptions:
    """What to analyse: a start/end trim and an optional zero-lag low-pass filter, all off by default."""

    lowpass_hz: float | None = None
    """Cut-off of a 4th-order Butterworth low-pass run forwards and backwards (scipy ``filtfilt``); None: raw."""
    trim_start_s: float = 0.0
    """Seconds dropped at the start (settling in)."""
    trim_end_s: float = 0.0
    """Seconds dropped at the end."""

    def issues(self, rate_hz: float, *, duration_s: float, pointer: str = "") -> list[Issue]:
        """Unusable options for a recording of ``duration_s`` sampled at ``rate_hz``."""
        out = [
            Issue(f"{pointer}/{name}", f"must be a finite number ≥ 0, got {getattr(self, name)!r}")
            for name in ("trim_start_s", "trim_end_s")
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0)
        ]
        lowest = 1 / duration_s  # one cycle over the recording: below it the filter passes nothing to measure
        if self.lowpass_hz is not None and not (lowest <= self.lowpass_hz < rate_hz / 2):
            out.append(
                Issue(
                    f"{pointer}/lowpass_hz",
                    f"must lie between one cycle over the recording ({lowest:.3g} Hz) and the Nyquist "
                    f"frequency {rate_hz / 2:g} Hz, got {self.lowpass_hz!r}",
                )
            )
        return out


@dataclass(frozen=True, eq=False)
class SwayMeasures:
    """The sway measures of one recording, lengths in its units and times in seconds (see `METHODS`).

    ``frequencies`` (K,) Hz and ``psd_x``, ``psd_y`` (K,) units²/Hz are the Welch spectra the frequency
    measures come from; ``not_estimated`` gives, for each measure that is NaN, the reason, and ``caveats``, for
    each that is coarse (frequencies of a stretch under `MIN_SPECTRAL_DURATION_S`), why."""

    rate_hz: float
    n_samples: int
    duration_s: float
    path_length: float
    mean_velocity: float
    mean_velocity_x: float
    mean_velocity_y: float
    mean_distance: float
    rms: float
    rms_x: float
    rms_y: float
    range_x: float
    range_y: float
    area95: float
    ellipse_major: float
    ellipse_minor: float
    ellipse_angle: float
    sway_area_per_second: float
    mean_frequency: float
    mean_frequency_x: float
    mean_frequency_y: float
    f95: float
    f95_x: float
    f95_y: float
    centre_x: float
    centre_y: float
    frequencies: np.ndarray
    psd_x: np.ndarray
    psd_y: np.ndarray
    not_estimated: dict[str, str] = field(default_factory=dict)
    caveats: dict[str, str] = field(default_factory=dict)

    def descriptors(self) -> dict[str, float]:
        """The scalar measures by name (everything but the rate, sample count, duration and spectra); NaN for
        those in ``not_estimated``."""
        skip = {
            "rate_hz",
            "n_samples",
            "duration_s",
            "frequencies",
            "psd_x",
            "psd_y",
            "not_estimated",
            "caveats",
        }
        return {f.name: float(getattr(self, f.name)) for f in fields(self) if f.name not in skip}

    def ellipse_outline(self, points: int = 181) -> np.ndarray:
        """(points, 2) x, y of the 95 % prediction ellipse around the mean COP, for pictures."""
        a = np.linspace(0.0, 2 * np.pi, points)
        angle = np.radians(self.ellipse_angle)
        u = np.stack([self.ellipse_major * np.cos(a), self.ellipse_minor * np.sin(a)], axis=1)
        rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        return u @ rotation.T + np.array([self.centre_x, self.centre_y])


def analysed_samples(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    options: SwayOptions = SwayOptions(),
    *,
    rate_hz: float | None = None,
) -> tuple[float, np.ndarray, np.ndarray]:
    """The rate and the x, y the measures use: trimmed, then filtered if asked. The rate is ``rate_hz`` where
    the recording states it (a C3D's), else read off the times (`sampling_rate`)."""
    t, x, y = (np.asarray(a, dtype=np.float64) for a in (t, x, y))
    if len(t) < MIN_SWAY_SAMPLES:
        check([Issue("/samples", f"has {len(t)} samples; sway measures need at least {MIN_SWAY_SAMPLES}")])
    rate = sampling_rate(t) if rate_hz is None else float(rate_hz)
    check(options.issues(rate, duration_s=len(t) / rate))
    keep = (t >= t[0] + options.trim_start_s - 0.5 / rate) & (t <= t[-1] - options.trim_end_s + 0.5 / rate)
    if keep.sum() < MIN_SWAY_SAMPLES:
        check(
            [
                Issue(
                    "/trim_start_s",
                    f"the trims leave {int(keep.sum())} samples of {len(t)}; sway measures need at least "
                    f"{MIN_SWAY_SAMPLES}",
                )
            ]
        )
    x, y = x[keep], y[keep]
    if options.lowpass_hz is not None:
        from scipy import signal

        sos = signal.butter(4, options.lowpass_hz, fs=rate, output="sos")
        x, y = signal.sosfiltfilt(sos, x), signal.sosfiltfilt(sos, y)
    return rate, x, y


def sway_measures(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    options: SwayOptions = SwayOptions(),
    *,
    rate_hz: float | None = None,
) -> SwayMeasures:
    """All sway measures of COP samples ``t`` (s, increasing), ``x``, ``y`` (any length unit) sampled at
    ``rate_hz`` where the recording states it (else read off ``t``); see `METHODS`.

    Frequency measures are NaN for an axis without power (the reason in ``not_estimated``) and carry a caveat
    below `MIN_SPECTRAL_DURATION_S` (``caveats``). Raises `InvalidInput` for fewer than `MIN_SWAY_SAMPLES` samples (after trimming) or
    unusable options."""
    from scipy import signal, stats

    rate, x, y = analysed_samples(t, x, y, options, rate_hz=rate_hz)
    n = len(x)
    duration = n / rate
    cx, cy = float(x.mean()), float(y.mean())
    xc, yc = x - cx, y - cy
    dx, dy = np.diff(x), np.diff(y)
    path = float(np.hypot(dx, dy).sum())

    cov = np.cov(xc, yc)
    eigenvalues, eigenvectors = np.linalg.eigh(cov)
    scale = 2 * (n + 1) * (n - 1) / (n * (n - 2)) * stats.f.ppf(ELLIPSE_P, 2, n - 2)
    major = eigenvectors[:, 1]
    angle = float(np.degrees(np.arctan2(major[1], major[0])))
    angle = angle - 180.0 if angle > 90.0 else angle + 180.0 if angle <= -90.0 else angle

    segment = n // 2
    welch = {"fs": rate, "window": "hann", "nperseg": segment, "noverlap": n // 4, "nfft": segment}
    frequencies, psd_x = signal.welch(xc, **welch)
    _, psd_y = signal.welch(yc, **welch)
    mean_fx, mean_fy = _mean_frequency(frequencies, psd_x), _mean_frequency(frequencies, psd_y)
    power_x, power_y = float(psd_x.sum()), float(psd_y.sum())
    total = power_x + power_y
    weighted = [
        (f, w) for f, w in ((mean_fx, power_x), (mean_fy, power_y)) if w > 0
    ]  # a still axis adds nothing
    mean_f = sum(f * w for f, w in weighted) / total if total > 0 else float("nan")
    spectral = {
        "mean_frequency": float(mean_f),
        "mean_frequency_x": mean_fx,
        "mean_frequency_y": mean_fy,
        "f95": _power_frequency(frequencies, psd_x + psd_y),
        "f95_x": _power_frequency(frequencies, psd_x),
        "f95_y": _power_frequency(frequencies, psd_y),
    }
    not_estimated = {
        name: "the COP never moves along this axis: its spectrum holds no power"
        if name[-2:] in ("_x", "_y")
        else "the COP never moves: its spectra hold no power"
        for name, value in spectral.items()
        if not np.isfinite(value)
    }

    return SwayMeasures(
        rate_hz=rate,
        n_samples=n,
        duration_s=duration,
        path_length=path,
        mean_velocity=path / duration,
        mean_velocity_x=float(np.abs(dx).sum() / duration),
        mean_velocity_y=float(np.abs(dy).sum() / duration),
        mean_distance=float(np.hypot(xc, yc).mean()),
        rms=float(np.sqrt(np.mean(xc**2 + yc**2))),
        rms_x=float(np.sqrt(np.mean(xc**2))),
        rms_y=float(np.sqrt(np.mean(yc**2))),
        range_x=float(np.ptp(x)),
        range_y=float(np.ptp(y)),
        area95=float(np.pi * scale * np.sqrt(max(np.linalg.det(cov), 0.0))),
        ellipse_major=float(np.sqrt(scale * max(eigenvalues[1], 0.0))),
        ellipse_minor=float(np.sqrt(scale * max(eigenvalues[0], 0.0))),
        ellipse_angle=angle,
        sway_area_per_second=float(np.abs(xc[:-1] * yc[1:] - xc[1:] * yc[:-1]).sum() / (2 * duration)),
        **spectral,
        centre_x=cx,
        centre_y=cy,
        frequencies=frequencies,
        psd_x=psd_x,
        psd_y=psd_y,
        not_estimated=not_estimated,
        caveats=_short_for_spectra(duration=duration, rate=rate, n=n),
    )


def _short_for_spectra(*, duration: float, rate: float, n: int) -> dict[str, str]:
    """The caveat on every frequency measure of a stretch under `MIN_SPECTRAL_DURATION_S` (to within half a
    sample): the values are the contract's, computed as for any trial, but on bins too coarse to read finely."""
    if n + 0.5 >= MIN_SPECTRAL_DURATION_S * rate:
        return {}
    reason = (
        f"the analysed {duration:.3g} s is shorter than the {MIN_SPECTRAL_DURATION_S:g} s the Welch spectra need "
        f"to resolve quiet standing's 0.1-0.5 Hz (their bins are {2 / duration:.3g} Hz apart): read it coarsely"
    )
    return dict.fromkeys(SPECTRAL, reason)


def _mean_frequency(f: np.ndarray, psd: np.ndarray) -> float:
    """``∫ f P df / ∫ P df`` by the trapezoid rule; NaN for a flat (zero-power) signal."""
    power = float(np.trapezoid(psd, f))
    return float(np.trapezoid(f * psd, f) / power) if power > 0 else float("nan")


def _power_frequency(f: np.ndarray, psd: np.ndarray, fraction: float = POWER_FRACTION) -> float:
    """The lowest frequency below which ``fraction`` of ``∫ P df`` lies (cumulative trapezoid)."""
    from scipy.integrate import cumulative_trapezoid

    area = cumulative_trapezoid(psd, f, initial=0.0)
    if not area[-1] > 0:
        return float("nan")
    return float(f[int(np.argmax(area >= fraction * area[-1]))])


CONFIDENCE = 0.95
N_RESAMPLES = 2000
SEED = 0
"""Bootstrap settings of `compare_groups`: 95 % percentile intervals from 2000 resamplings, seeded so the
same trials give the same intervals."""


@dataclass(frozen=True)
class Interval:
    """An estimate with its 95 % interval (low and high None where a group has fewer than two trials)."""

    value: float
    low: float | None
    high: float | None


@dataclass(frozen=True)
class GroupComparison:
    """Per group: trials and each measure's mean; per ordered pair (a, b) of groups each measure's b − a."""

    n: dict[str, int]
    means: dict[str, dict[str, Interval]]
    differences: dict[tuple[str, str], dict[str, Interval]]


def compare_groups(groups: dict[str, dict[str, np.ndarray]]) -> GroupComparison:
    """Means per group and differences between groups (in the given order, b − a for every a before b) of
    each measure, with 95 % percentile-bootstrap intervals (`bootstrap_intervals`). ``groups[label][measure]``
    holds one value per trial."""
    labels = list(groups)
    names = list(next(iter(groups.values()), {}))
    data = {
        g: np.array([groups[g][m] for m in names], dtype=np.float64) for g in labels
    }  # (measures, trials)
    means = {g: bootstrap_intervals(names, (data[g],), _mean) for g in labels}
    differences = {
        (a, b): bootstrap_intervals(names, (data[a], data[b]), _difference)
        for i, a in enumerate(labels)
        for b in labels[i + 1 :]
    }
    return GroupComparison(n={g: data[g].shape[1] for g in labels}, means=means, differences=differences)


def quotient(numerator: dict[str, np.ndarray], denominator: dict[str, np.ndarray]) -> dict[str, Interval]:
    """Per measure the ratio of two groups' means (e.g. the Romberg quotient, eyes closed / eyes open) with a
    95 % percentile-bootstrap interval (`bootstrap_intervals`)."""
    names = list(numerator)
    top = np.array([numerator[m] for m in names], dtype=np.float64)
    bottom = np.array([denominator[m] for m in names], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return bootstrap_intervals(names, (top, bottom), _ratio)


def bootstrap_intervals(
    names: list[str], samples: tuple[np.ndarray, ...], statistic: Callable[..., np.ndarray]
) -> dict[str, Interval]:
    """``statistic`` of (measures, trials) ``samples`` per measure with a 95 % percentile interval from
    ``scipy.stats.bootstrap`` (`motion.bootstrap`: trials resampled within each sample, seeded); no interval below
    two trials."""
    estimate = statistic(*samples)
    rng = np.random.default_rng(SEED)
    interval = (
        None
        if min(s.shape[1] for s in samples) < 2
        else percentile_interval(samples, statistic, n_resamples=N_RESAMPLES, rng=rng, confidence=CONFIDENCE)
    )
    if interval is None:
        return {m: Interval(float(e), None, None) for m, e in zip(names, estimate, strict=True)}
    return {
        m: Interval(float(e), float(lo), float(hi))
        for m, e, lo, hi in zip(names, estimate, *interval, strict=True)
    }


def _mean(x: np.ndarray, axis: int = -1) -> np.ndarray:
    """Mean over trials."""
    return np.mean(x, axis=axis)


def _difference(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """Mean of b minus mean of a."""
    return np.mean(b, axis=axis) - np.mean(a, axis=axis)


def _ratio(a: np.ndarray, b: np.ndarray, axis: int = -1) -> np.ndarray:
    """Mean of a over mean of b."""
    return np.mean(a, axis=axis) / np.mean(b, axis=axis)
