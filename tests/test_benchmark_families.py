"""The families benchmark's margin over no sharing: paired world by world, with its standard error."""

from __future__ import annotations

from benchmarks.families import paired_margin


def test_the_margin_pairs_worlds_and_gives_the_standard_error_of_the_differences() -> None:
    # Differences 0.2 and 0.3 (world 2 has no "none" fit and is left out): mean 0.25, s.e. 0.05.
    assert paired_margin({0: 0.3, 1: 0.5, 2: 0.9}, {0: 0.1, 1: 0.2}) == "+0.250 ± 0.050"


def test_the_margin_needs_two_worlds_both_configs_fitted() -> None:
    assert paired_margin({0: 0.3}, {0: 0.1, 1: 0.2}) == "—"
