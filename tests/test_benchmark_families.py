"""The families benchmark's margin over no sharing: paired world by world, with its standard error; its
figure, drawn from whatever fits the cache holds; and its families' tasks."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from benchmarks.families import ENGINE, Family, choice_table, key_of, paired_margin, plot, table, tasks_of
from metairl_engine.sim.objectworld import make_objectworld


def fit_row(variant: str, world: int, *, demos: int = 3, **scores: Any) -> dict[str, Any]:
    """A cached fit of ``variant`` on multi-objectworld's ``world`` with these scores, keyed as today's engine."""
    head = {"family": "multi-objectworld", "demos": demos, "variant": variant, "key": key_of(variant)}
    return {**head, "world": world, **scores}


def test_the_margin_pairs_worlds_and_gives_the_standard_error_of_the_differences() -> None:
    # Differences 0.2 and 0.3 (world 2 has no "none" fit and is left out): mean 0.25, s.e. 0.05.
    assert paired_margin({0: 0.3, 1: 0.5, 2: 0.9}, {0: 0.1, 1: 0.2}) == "+0.250 ± 0.050"


def test_the_margin_needs_two_worlds_both_configs_fitted() -> None:
    assert paired_margin({0: 0.3}, {0: 0.1, 1: 0.2}) == "—"


def test_the_choice_table_pairs_auto_with_the_default_and_counts_the_place_alone() -> None:
    rows = [
        fit_row(v, w, pearson=pearson[w], evd_random=0.5, task_features=chosen[w])
        for v, pearson, chosen in (
            ("auto", [0.5, 0.6, 0.7], ["no", "yes", "yes"]),
            ("default", [0.3, 0.6, 0.5], [None] * 3),
            ("none", [0.1, 0.1, 0.1], [None] * 3),
        )
        for w in range(3 if v == "auto" else 2)  # world 2 has no default or none fit: left out
    ]
    [line] = choice_table(rows, first=0, worlds=6, engine=ENGINE).splitlines()[2:]
    assert line == (
        "| multi-objectworld | 3 | 0.550 | 0.450 | +0.100 ± 0.100 | +0.450 ± 0.050 | 0.500 | 0.500 | 0.500 | "
        "1 of 2 |"
    )


def test_the_figure_is_drawn_from_the_fits_there_are(tmp_path: Path) -> None:
    rows = [
        fit_row(v, w, demos=demos, pearson=p)
        for demos in (3, 10)
        for v, p in (("default", 0.5), ("none", 0.2))
        for w in (0, 1)
    ]
    figure = tmp_path / "families.png"
    plot(rows, 6, figure)  # every other family and the engine before have no fits: left out, not an error
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_other_worlds_table_averages_only_worlds_from_its_first_and_lists_only_fitted_rows() -> None:
    rows = [
        fit_row(
            v,
            w,
            pearson=p + (0.5 if w < 6 else 0.0),  # the table's worlds would lift the mean by 0.5
            evd_random=0.1,
            epic=0.2,
        )
        for v, p in (("default", 0.4), ("none", 0.1))
        for w in (0, 1, 6, 7)
    ]
    lines = table(rows, ["default", "none"], 12, first=6).splitlines()
    assert len(lines) == 3  # header, rule, the one family and demonstration count fitted on worlds 6 … 11
    assert lines[2].startswith("| multi-objectworld | 3 | 0.400 | 0.100 |")
    assert lines[2].endswith("| +0.300 ± 0.000 | 2 |")


def test_a_family_gives_its_tasks_their_count_and_demonstrator() -> None:
    world = make_objectworld(seed=0, size=6)[0]
    careful = Family(lambda i: world, multi=True, demos=(2,), n_tasks=3, rationality=50.0)
    noisy = replace(careful, rationality=0.01)

    sims = tasks_of(careful, world, 0, 2)
    assert len(sims) == 3 and all(len(s.trajectories) == 2 for s in sims)
    # A near-greedy demonstrator takes other steps than a near-uniform one from the same seeds.
    assert [t.actions.tolist() for s in sims for t in s.trajectories] != [
        t.actions.tolist() for s in tasks_of(noisy, world, 0, 2) for t in s.trajectories
    ]
