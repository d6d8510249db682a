"""docs/examples/motion_tutorial.py end to end against a real `metairl serve`: simulate the patient as CSV,
upload both sessions, fit, and print Table I (visited / all states) with a heatmap per reward."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from metairl_engine.motion.recording import DiscretiseSettings, demonstrations
from metairl_engine.sim.patient import PatientSettings, simulate_patient
from tests.served import REPO, metairl_serve

pytestmark = [pytest.mark.worker, pytest.mark.slow]

SCRIPT = REPO / "docs" / "examples" / "motion_tutorial.py"
SIZE = 12
ROW = re.compile(r"^  (\S.*?)\s+([+-]\d\.\d{3}) / ([+-]\d\.\d{3})$", re.MULTILINE)
"""A Table I line: label, Pearson on visited states, Pearson on all states."""


def tutorial(*args: str | int | Path) -> subprocess.CompletedProcess[str]:
    """Run the tutorial script with these arguments (exit code checked by the caller)."""
    command = [sys.executable, str(SCRIPT), *map(str, args)]
    return subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=600)


def test_the_tutorial_prints_table_i_per_session_and_saves_a_heatmap_per_reward(tmp_path: Path) -> None:
    data = tmp_path / "patient"
    simulated = tutorial("simulate", "--out", data, "--size", SIZE)
    assert simulated.returncode == 0, simulated.stderr
    patient = simulate_patient(PatientSettings(width=SIZE, height=SIZE))
    with metairl_serve(tmp_path) as served:
        run = tutorial(
            "run", "--data", data, "--size", SIZE, "--max-steps", 20, "--url", served.url, "--key", served.key
        )
    assert run.returncode == 0, run.stdout + run.stderr
    for session, recording in patient.sessions.items():
        cut = demonstrations(recording, discretise_settings=DiscretiseSettings(width=SIZE, height=SIZE))
        block = run.stdout.split(f"\n{session}: fit in ")[1].split("\n\n")[0]
        labels = [label for label, _, _ in ROW.findall(block)]
        assert sorted(labels) == sorted([*cut.by_label, "origin"]), block
        for label, visited, everywhere in ROW.findall(block):
            assert -1 <= float(visited) <= 1 and -1 <= float(everywhere) <= 1
            assert (data / f"{session}-{label.replace(' ', '-')}.png").read_bytes()[:4] == b"\x89PNG"
