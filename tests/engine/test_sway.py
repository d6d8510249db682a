"""Sway measures: the published values of a public balance data set, the options, a known geometry."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from metairl_engine import InvalidInput
from metairl_engine.motion.sway import SwayOptions, sway_measures
from tests.shared_data import shared_data

TOLERANCE = {
    "area95": ("COParea", 0.01),
    "mean_velocity": ("COPvelo", 0.01),
    "mean_frequency": ("COPmfreq", 0.02),
}


def hbedb_errors() -> dict[str, list[float]]:
    """Relative error of each contract measure against the data set's own value, trial by trial."""
    folder = shared_data("hbedb")
    with (folder / "reference-descriptors.tsv").open() as fh:
        reference = list(csv.DictReader(fh, delimiter="\t"))
    errors: dict[str, list[float]] = {name: [] for name in TOLERANCE}
    for row in reference:
        data = np.loadtxt(folder / f"{row['Trial']}.txt", skiprows=1)
        measures = sway_measures(data[:, 0], data[:, 7], data[:, 8]).descriptors()
        for name, (column, _) in TOLERANCE.items():
            errors[name].append(abs(measures[name] / float(row[column]) - 1))
    return errors


def test_area_velocity_and_mean_frequency_reproduce_the_published_values_of_every_hbedb_trial() -> None:
    errors = hbedb_errors()
    assert len(errors["area95"]) == 48
    for name, (_, tolerance) in TOLERANCE.items():
        assert max(errors[name]) < tolerance, (name, max(errors[name]))


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
