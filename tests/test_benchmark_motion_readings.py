"""``python -m benchmarks.motion readings``: every reading of a session's fit scored against the true preference."""

from __future__ import annotations

import math

import pytest

from benchmarks.motion import SessionReadings, agreement_patient, session_readings
from benchmarks.motion_readings import COMPARISON, READINGS, SessionFit
from metairl_engine import FitConfig
from metairl_engine.motion.readout import direction_readout

SIZE = 8
"""The smallest grid the controller patient allows."""

QUICK = FitConfig(max_steps=3)
"""A few steps: the readings' plumbing, not the fit's quality, is under test."""


@pytest.fixture(scope="module")
def found() -> dict[str, SessionReadings]:
    patient = agreement_patient("controller, weak left", SIZE, 0)

    def truth(fit: SessionFit) -> dict[str, float]:
        return direction_readout(patient.ideal_reward, fit.visited, width=SIZE, height=SIZE)

    def truth_reversed(fit: SessionFit) -> dict[str, float]:
        return {d: -v for d, v in truth(fit).items()}

    readings = READINGS | COMPARISON | {"truth": truth, "truth reversed": truth_reversed}
    return session_readings(patient, config=QUICK, readings=readings)


def test_every_reading_gives_one_finite_spearman_per_session(found: dict[str, SessionReadings]) -> None:
    assert list(found) == ["unstimulated", "stimulated"]
    for session in found.values():
        assert list(session.scores) == [*READINGS, *COMPARISON, "truth", "truth reversed"]
        assert all(math.isfinite(v) and -1 <= v <= 1 for v in session.scores.values()), session.scores
        assert math.isfinite(session.drift_spearman)
        assert len(session.offsets) == len(session.drift) == 8


def test_a_reading_of_the_truth_scores_plus_one_and_its_reverse_minus_one(
    found: dict[str, SessionReadings],
) -> None:
    for session in found.values():
        assert session.scores["truth"] == pytest.approx(1.0)
        assert session.scores["truth reversed"] == pytest.approx(-1.0)
