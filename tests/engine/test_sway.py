"""Sway measures: the published values of a public balance data set, the options, a known geometry."""

from __future__ import annotations

import csv
from functools import cache

import numpy as np
import pytest

from metairl_engine import InvalidInput
from metairl_engine.motion.sway import (
    LENGTH_POWER,
    MIN_SPECTRAL_DURATION_S,
    SPECTRAL,
    SwayOptions,
    sway_measures,
)
from tests.shared_data import shared_data

COLUMNS = {"area95": "COParea", "mean_velocity": "COPvelo", "mean_frequency": "COPmfreq"}


@cache
def hbedb_trials() -> list[tuple[dict[str, str], np.ndarray]]:
    """Every trial's reference row and its (N, 3) time, COPx, COPy as read (float64)."""
    folder = shared_data("hbedb")
    with (folder / "reference-descriptors.tsv").open() as fh:
        reference = list(csv.DictReader(fh, delimiter="\t"))
    return [(row, np.loadtxt(folder / f"{row['Trial']}.txt", skiprows=1)[:, [0, 7, 8]]) for row in reference]


def hbedb_errors(dtype: type[np.floating]) -> dict[str, float]:
    """Largest relative error of each contract measure against the data set's own values, the samples held
    as ``dtype`` first."""
    errors = dict.fromkeys(COLUMNS, 0.0)
    for row, data in hbedb_trials():
        t, x, y = data.astype(dtype).astype(np.float64).T
        measures = sway_measures(t, x, y).descriptors()
        for name, column in COLUMNS.items():
            errors[name] = max(errors[name], abs(measures[name] / float(row[column]) - 1))
    return errors


def test_area_velocity_and_mean_frequency_reproduce_the_published_values_of_every_hbedb_trial() -> None:
    assert len(hbedb_trials()) == 48
    for name, error in hbedb_errors(np.float64).items():
        assert error < 1e-11, (name, error)


def test_samples_stored_as_float32_give_the_published_velocity_and_frequency_within_1e_6() -> None:
    """The service stores samples as float32: rounded times must not bias the rate (a median interval of
    float32 times is 2.3e-5 off at 100 Hz over 60 s)."""
    for name, error in hbedb_errors(np.float32).items():
        assert error < 1e-6, (name, error)


@pytest.mark.parametrize(
    ("rate", "seconds"), [(2000.0, 0.58), (600.0, 19.7), (100.0, 60.0), (1000.0, 1200.0)]
)
def test_the_rate_of_uniform_float32_times_is_their_span_not_a_rounded_interval(
    rate: float, seconds: float
) -> None:
    """Times as a plate file's are stored: the rate and duration within 1e-6 of the true ones."""
    n = round(rate * seconds)
    t = (np.arange(n) / rate).astype(np.float32)
    x = np.sin(np.arange(n) / rate)
    m = sway_measures(t, x, np.cos(np.arange(n) / rate))
    assert m.rate_hz == pytest.approx(rate, rel=1e-6) and m.duration_s == pytest.approx(n / rate, rel=1e-6)


def test_a_gap_in_the_times_keeps_the_rate_of_the_samples_present() -> None:
    """Ten samples missing: the span would count time not sampled, so the median interval gives the rate."""
    t = np.delete(np.arange(3000) / 100, np.arange(1000, 1010))
    m = sway_measures(t, np.sin(t), np.cos(t))
    assert m.rate_hz == pytest.approx(100.0, rel=1e-9) and m.duration_s == pytest.approx(29.9, rel=1e-9)


def test_every_measure_carries_its_power_of_the_length_unit() -> None:
    t, x, y = circle()
    assert set(sway_measures(t, x, y).descriptors()) == set(LENGTH_POWER)


@pytest.mark.parametrize(("rate", "n"), [(1000.0, 8), (100.0, 1990), (600.0, 11824)])
def test_a_trial_shorter_than_20_s_has_its_frequency_measures_with_a_caveat(rate: float, n: int) -> None:
    """8 samples at 1000 Hz (a C3D test file), 19.9 s at 100 Hz, 19.7 s at 600 Hz: Welch bins over 0.1 Hz apart."""
    t = np.arange(n) / rate
    m = sway_measures(t, np.sin(7 * t) + 0.01 * np.sin(900 * t), np.cos(5 * t))
    descriptors = m.descriptors()
    assert set(m.caveats) == set(SPECTRAL) and m.not_estimated == {}
    assert all(np.isfinite(descriptors[name]) for name in SPECTRAL)
    assert f"{MIN_SPECTRAL_DURATION_S:g} s" in m.caveats["mean_frequency"]


def test_a_trial_of_20_s_has_its_frequency_measures_but_not_those_of_an_axis_that_never_moves() -> None:
    t, x, y = circle(seconds=20.0)
    m = sway_measures(t, x, y)
    assert m.not_estimated == m.caveats == {} and m.mean_frequency == pytest.approx(0.5, abs=0.02)
    still = sway_measures(t, x, 0 * y)
    assert set(still.not_estimated) == {"mean_frequency_y", "f95_y"} and np.isnan(still.mean_frequency_y)
    assert "never moves" in still.not_estimated["f95_y"] and still.mean_frequency == pytest.approx(
        0.5, abs=0.02
    )


def circle(rate: float = 100.0, seconds: float = 20.0, hz: float = 0.5, radius: float = 2.0) -> tuple:
    """A COP going round a circle ``hz`` times a second."""
    t = np.arange(int(rate * seconds)) / rate
    return t, radius * np.cos(2 * np.pi * hz * t), radius * np.sin(2 * np.pi * hz * t)


def test_a_circle_has_its_circumference_per_turn_as_velocity_and_its_frequency() -> None:
    t, x, y = circle()
    m = sway_measures(t, x, y)
    assert m.mean_velocity == pytest.approx(2 * np.pi * 2.0 * 0.5, rel=1e-3)
    assert m.mean_distance == pytest.approx(2.0, rel=1e-9)
    assert m.rms_x == pytest.approx(np.sqrt(2.0), rel=1e-6)
    assert m.range_x == pytest.approx(4.0, rel=1e-3)
    assert m.mean_frequency == pytest.approx(0.5, abs=0.02)
    assert 0.5 <= m.f95 <= 0.8  # Hann leakage over 0.1-Hz bins
    assert m.ellipse_major == pytest.approx(m.ellipse_minor, rel=1e-3)
    assert m.sway_area_per_second == pytest.approx(np.pi * 4.0 * 0.5, rel=1e-3)


def test_an_ellipse_along_a_diagonal_has_its_angle() -> None:
    t, x, y = circle(radius=1.0)
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    m = sway_measures(t, 3 * x * c - y * s, 3 * x * s + y * c)
    assert m.ellipse_angle == pytest.approx(45.0, abs=0.1)
    assert m.ellipse_major / m.ellipse_minor == pytest.approx(3.0, rel=1e-3)
    outline = m.ellipse_outline()
    assert outline.shape == (181, 2)


def test_trim_and_lowpass_change_what_is_analysed() -> None:
    rng = np.random.default_rng(1)
    t, x, y = circle()
    x, y = x + rng.normal(0, 0.05, len(t)), y + rng.normal(0, 0.05, len(t))
    raw = sway_measures(t, x, y)
    trimmed = sway_measures(t, x, y, SwayOptions(trim_start_s=5.0, trim_end_s=5.0))
    filtered = sway_measures(t, x, y, SwayOptions(lowpass_hz=5.0))
    assert trimmed.n_samples == raw.n_samples - 1000
    assert trimmed.duration_s == pytest.approx(10.0)
    assert filtered.mean_velocity == pytest.approx(2 * np.pi, rel=0.02)
    assert raw.mean_velocity > 1.4 * filtered.mean_velocity
    assert filtered.mean_frequency < raw.mean_frequency


@pytest.mark.parametrize(
    ("options", "pointer"),
    [
        (SwayOptions(lowpass_hz=60.0), "/lowpass_hz"),
        (SwayOptions(lowpass_hz=1e-12), "/lowpass_hz"),  # below one cycle per recording: nothing to measure
        (SwayOptions(trim_start_s=-1.0), "/trim_start_s"),
        (SwayOptions(trim_start_s=15.0, trim_end_s=5.0), "/trim_start_s"),
    ],
)
def test_unusable_options_name_their_field(options: SwayOptions, pointer: str) -> None:
    t, x, y = circle()
    with pytest.raises(InvalidInput) as caught:
        sway_measures(t, x, y, options)
    assert caught.value.issues[0].pointer == pointer
