"""The controller patient: seeded, not a planner, weak on one side, less reach unstimulated."""

import numpy as np
import pytest

from metairl_engine import validate_trajectories
from metairl_engine.errors import InvalidInput
from metairl_engine.grids import DIRECTION_NAMES, grid_mdp
from metairl_engine.motion.recording import NO_INSTRUCTION, DiscretiseSettings, demonstrations
from metairl_engine.sim.controller_patient import (
    ControllerPatient,
    ControllerSettings,
    preference_map,
    side_reach,
    simulate_controller_patient,
)

SIZE = 20
SETTINGS = ControllerSettings(width=SIZE, height=SIZE, repetitions=2)


@pytest.fixture(scope="module")
def patient() -> ControllerPatient:
    return simulate_controller_patient(SETTINGS)


def test_simulation_is_seeded(patient: ControllerPatient) -> None:
    again = simulate_controller_patient(SETTINGS)
    other = simulate_controller_patient(ControllerSettings(width=SIZE, height=SIZE, repetitions=2, seed=1))
    for name, rec in patient.sessions.items():
        np.testing.assert_array_equal(rec.x, again.sessions[name].x)
        assert len(rec.x) != len(other.sessions[name].x) or not np.array_equal(rec.x, other.sessions[name].x)


def test_recordings_rest_without_instruction_and_move_with_one(patient: ControllerPatient) -> None:
    for rec in patient.sessions.values():
        assert rec.sample_rate == pytest.approx(100.0)
        assert rec.instruction is not None
        assert set(rec.instruction.tolist()) == {NO_INSTRUCTION, *DIRECTION_NAMES}
        assert rec.instruction[0] == rec.instruction[-1] == NO_INSTRUCTION


def test_pipeline_cuts_every_movement_into_valid_demonstrations(patient: ControllerPatient) -> None:
    mdp = grid_mdp(width=SIZE, height=SIZE, velocity=True, gamma=0.9)
    for rec in patient.sessions.values():
        demos = demonstrations(rec, discretise_settings=DiscretiseSettings(width=SIZE, height=SIZE))
        assert {k: len(v) for k, v in demos.by_label.items()} == dict.fromkeys(DIRECTION_NAMES, 2)
        for trajectories in demos.by_label.values():
            validate_trajectories(mdp, trajectories)


def test_preference_is_a_cell_map_with_a_valley_on_the_weak_side(patient: ControllerPatient) -> None:
    assert patient.preference.shape == (SIZE * SIZE,)
    np.testing.assert_array_equal(patient.ideal_reward, np.tile(patient.preference, 8))
    u = np.array([-0.6, 0.6, 0.0, 0.0])
    v = np.array([0.0, 0.0, 0.6, -0.6])
    left, right, forward, backward = preference_map(u, v, "left")
    assert left < min(right, forward, backward)
    assert preference_map(u, v, "right")[1] < preference_map(u, v, "right")[0]


def test_weak_side_loses_reach_and_its_neighbours_half_as_much() -> None:
    assert side_reach("left", "left", 0.4) == pytest.approx(0.6)
    assert side_reach("forward left", "left", 0.4) == pytest.approx(0.8)
    assert side_reach("right", "left", 0.4) == side_reach("forward", "left", 0.4) == 1.0


def test_the_weak_side_reaches_least_and_stimulation_reaches_farther(patient: ControllerPatient) -> None:
    peak = {}
    for name, rec in patient.sessions.items():
        assert rec.instruction is not None
        dist = np.hypot(rec.x, rec.y)  # the plate is centred on (0, 0)
        peak[name] = {d: float(dist[rec.instruction == d].max()) for d in DIRECTION_NAMES}
        others = [v for d, v in peak[name].items() if d != "left"]
        assert peak[name]["left"] < min(others)
    assert all(peak["stimulated"][d] > peak["unstimulated"][d] for d in DIRECTION_NAMES)


def test_unstimulated_session_is_noisier(patient: ControllerPatient) -> None:
    def jitter(name: str) -> float:
        rec = patient.sessions[name]
        return float(np.std(np.diff(rec.x, 2)))

    assert jitter("unstimulated") > jitter("stimulated")


def test_bad_settings_are_named() -> None:
    with pytest.raises(InvalidInput) as exc:
        simulate_controller_patient(ControllerSettings(width=4, weak_side="up", weakness=1.5))
    assert {i.pointer for i in exc.value.issues} == {
        "/patient/width",
        "/patient/weak_side",
        "/patient/weakness",
    }
