"""benchmarks/RESULTS.md is what ``python -m benchmarks.results`` writes from the stored result files, and
states today's facts only."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from benchmarks import results

REPO = Path(__file__).resolve().parents[1]
HISTORY = re.compile(r"session [0-9]|\brev[0-9]|issue [0-9]|issue #", re.IGNORECASE)


def test_the_committed_page_is_what_the_stored_results_give() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "benchmarks.results", "--check"], cwd=REPO, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr


def test_check_fails_on_a_stale_page(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    stale = tmp_path / "RESULTS.md"
    stale.write_text(results.page().replace("Sharing gain", "Sharing loss"))
    monkeypatch.setattr(results, "PAGE", stale)
    assert results.main(["--check"]) == 1


def test_a_families_page_is_included_under_accuracy_per_family(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    families = tmp_path / "FAMILIES.md"
    families.write_text(
        "# Families\n\n## Objectworld\n\n| family | default |\n| --- | --- |\n| objectworld | 0.5 |\n"
    )
    monkeypatch.setattr(results, "FAMILIES", families)
    text = results.page()
    section = text.split("\n## ")[1]
    assert section.startswith("Accuracy per family")
    assert "### Objectworld" in section and "| objectworld | 0.5 |" in section


def test_every_table_names_its_command_and_provenance() -> None:
    text = results.page()
    for section in text.split("\n## ")[1:]:
        if "| --- |" in section:
            assert "python -m benchmarks." in section, section.splitlines()[0]
            assert "Machine:" in section or "Provenance not recorded" in section, section.splitlines()[0]


def test_the_page_holds_no_history() -> None:
    assert not HISTORY.findall(results.page())


def test_the_machines_of_rows_are_their_processors_and_rows_without_provenance_name_none() -> None:
    rows: list[dict[str, Any]] = [
        {"provenance": {"machine": {"cpu": "AMD EPYC"}}},
        {"provenance": {"machine": {"cpu": "Intel Xeon"}}},
        {"provenance": {"machine": {}}},
        {"variant": "none"},
    ]
    assert results.machines(rows) == {"AMD EPYC", "Intel Xeon", results.UNRECORDED}
    assert results.machines(rows[3:]) == set()
