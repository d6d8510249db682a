"""The synthetic patient: seeded, realistic enough for the motion pipeline, with a known ideal reward."""

import numpy as np
import pytest

from metairl_engine import validate_trajectories
from metairl_engine.grids import DIRECTION_NAMES, grid_mdp
from metairl_engine.motion.recording import DiscretiseSettings, Recording, demonstrations, segment
from metairl_engine.sim.patient import (
    DIRECTION_PREFERENCE,
    PatientSettings,
    SyntheticPatient,
    ideal_reward,
    simulate_patient,
)

SIZE = 30
SETTINGS = PatientSettings(width=SIZE, height=SIZE)


@pytest.fixture(scope="module")
def patient() -> SyntheticPatient:
    return simulate_patient(SETTINGS)


def test_simulation_is_seeded(patient: SyntheticPatient) -> None:
    again = simulate_patient(SETTINGS)
    other = simulate_patient(PatientSettings(width=SIZE, height=SIZE, seed=1))
    for name, rec in patient.sessions.items():
        np.testing.assert_array_equal(rec.x, again.sessions[name].x)
        assert len(rec.x) != len(other.sessions[name].x) or not np.array_equal(rec.x, other.sessions[name].x)


def test_sessions_are_valid_100_hz_recordings_with_instructions(patient: SyntheticPatient) -> None:
    assert set(patient.sessions) == {"unstimulated", "stimulated"}
    for rec in patient.sessions.values():
        assert rec.sample_rate == pytest.approx(100.0)
        assert rec.instruction is not None
        assert set(rec.instruction.tolist()) == {"", *DIRECTION_NAMES}
        b = rec.bounds
        assert b.x_min <= rec.x.min() and rec.x.max() <= b.x_max


def test_ideal_reward_is_a_centre_bump_weaker_backward_left(patient: SyntheticPatient) -> None:
    r = patient.ideal_reward.reshape(8, SIZE, SIZE)  # (direction, y, x)
    assert patient.ideal_reward.shape == (8 * SIZE * SIZE,)
    np.testing.assert_array_equal(patient.ideal_reward, ideal_reward(width=SIZE, height=SIZE))
    centre, quarter = SIZE // 2, SIZE // 4
    assert (
        r[0, centre, centre]
        > r[0, centre + quarter, centre + quarter]
        > r[0, centre - quarter, centre - quarter]
    )


def test_ideal_reward_adds_a_preference_per_direction_of_motion(patient: SyntheticPatient) -> None:
    r = patient.ideal_reward.reshape(8, SIZE, SIZE)
    for d, preference in enumerate(DIRECTION_PREFERENCE):
        np.testing.assert_allclose(r[d] - r[0], preference - DIRECTION_PREFERENCE[0])
    assert np.argmin(DIRECTION_PREFERENCE) == DIRECTION_NAMES.index("backward left")
    flat = ideal_reward(width=SIZE, height=SIZE, direction_preference=(0.0,) * 8).reshape(8, SIZE, SIZE)
    np.testing.assert_array_equal(flat[0], flat[5])


def test_the_costly_direction_is_demonstrated_less_than_without_the_preference(
    patient: SyntheticPatient,
) -> None:
    def action_counts(sim: SyntheticPatient) -> np.ndarray:
        counts = np.zeros(8)
        for rec in sim.sessions.values():
            demos = demonstrations(rec, discretise_settings=DiscretiseSettings(width=SIZE, height=SIZE))
            for trajectories in demos.by_label.values():
                for t in trajectories:
                    counts += np.bincount(t.actions, minlength=8)
        return counts

    flat = simulate_patient(PatientSettings(width=SIZE, height=SIZE, direction_preference=(0.0,) * 8))
    costly = DIRECTION_NAMES.index("backward left")
    assert action_counts(patient)[costly] < 0.7 * action_counts(flat)[costly]


def test_each_task_reward_peaks_in_its_instructed_direction(patient: SyntheticPatient) -> None:
    for k, name in enumerate(DIRECTION_NAMES):
        extra = (patient.task_rewards[name] - patient.ideal_reward).reshape(8, SIZE, SIZE)[0]
        y, x = np.unravel_index(np.argmax(extra), extra.shape)
        angle = np.arctan2(y - SIZE // 2, x - SIZE // 2)
        assert abs(np.angle(np.exp(1j * (angle - k * np.pi / 4)))) < np.pi / 8


def test_pipeline_finds_every_instructed_movement(patient: SyntheticPatient) -> None:
    mdp = grid_mdp(width=SIZE, height=SIZE, velocity=True, gamma=0.9)
    for rec in patient.sessions.values():
        demos = demonstrations(rec, discretise_settings=DiscretiseSettings(width=SIZE, height=SIZE))
        assert {k: len(v) for k, v in demos.by_label.items()} == dict.fromkeys(
            DIRECTION_NAMES, SETTINGS.repetitions
        )
        for trajectories in demos.by_label.values():
            validate_trajectories(mdp, trajectories)


def test_stimulated_movements_follow_the_instruction_more_closely(patient: SyntheticPatient) -> None:
    def mean_heading_error(rec: Recording) -> float:
        assert rec.instruction is not None
        errors = []
        for seg in segment(rec):
            angle = np.arctan2(rec.y[seg.peak], rec.x[seg.peak])  # the plate is centred on (0, 0)
            wanted = DIRECTION_NAMES.index(seg.label) * np.pi / 4
            errors.append(abs(np.angle(np.exp(1j * (angle - wanted)))))
        return float(np.mean(errors))

    assert mean_heading_error(patient.sessions["stimulated"]) < mean_heading_error(
        patient.sessions["unstimulated"]
    )


def test_unlabelled_stimulated_session_is_labelled_by_direction(patient: SyntheticPatient) -> None:
    rec = patient.sessions["stimulated"]
    assert rec.instruction is not None
    segs = segment(Recording(t=rec.t, x=rec.x, y=rec.y, bounds=rec.bounds))
    assert [s.label for s in segs] == [rec.instruction[s.peak] for s in segs]
    assert len(segs) == len(DIRECTION_NAMES) * SETTINGS.repetitions


def test_four_direction_protocol() -> None:
    four = ("forward", "backward", "left", "right")
    sim = simulate_patient(PatientSettings(width=SIZE, height=SIZE, directions=four, repetitions=2))
    demos = demonstrations(
        sim.sessions["stimulated"], discretise_settings=DiscretiseSettings(width=SIZE, height=SIZE)
    )
    assert {k: len(v) for k, v in demos.by_label.items()} == dict.fromkeys(four, 2)
    assert set(sim.task_rewards) == set(four)
