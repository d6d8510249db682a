"""The families benchmark's margin over no sharing: paired world by world, with its standard error; and its
figure, drawn from whatever fits the cache holds."""

from __future__ import annotations

from pathlib import Path

from benchmarks.families import key_of, paired_margin, plot


def test_the_margin_pairs_worlds_and_gives_the_standard_error_of_the_differences() -> None:
    # Differences 0.2 and 0.3 (world 2 has no "none" fit and is left out): mean 0.25, s.e. 0.05.
    assert paired_margin({0: 0.3, 1: 0.5, 2: 0.9}, {0: 0.1, 1: 0.2}) == "+0.250 ± 0.050"


def test_the_margin_needs_two_worlds_both_configs_fitted() -> None:
    assert paired_margin({0: 0.3}, {0: 0.1, 1: 0.2}) == "—"


def test_the_figure_is_drawn_from_the_fits_there_are(tmp_path: Path) -> None:
    rows = [
        {
            "family": "multi-objectworld",
            "demos": demos,
            "variant": v,
            "key": key_of(v),
            "world": w,
            "pearson": p,
        }
        for demos in (3, 10)
        for v, p in (("default", 0.5), ("none", 0.2))
        for w in (0, 1)
    ]
    figure = tmp_path / "families.png"
    plot(rows, 6, figure)  # every other family and the engine before have no fits: left out, not an error
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
