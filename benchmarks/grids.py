"""Time `grid_mdp` builds (including validation) at the paper's 100×100 size: ``python -m benchmarks.grids``."""

from __future__ import annotations

import time

from metairl_engine.grids import grid_mdp

CASES: tuple[tuple[str, dict[str, object]], ...] = (
    ("plain 100×100, 4 moves", {"width": 100, "height": 100}),
    (
        "plain 100×100, 8 moves + stay, slip 0.1",
        {"width": 100, "height": 100, "moves": 8, "stay": True, "slip": 0.1},
    ),
    ("velocity 100×100 (80,000 states)", {"width": 100, "height": 100, "velocity": True}),
    ("velocity 100×100, slip 0.1", {"width": 100, "height": 100, "velocity": True, "slip": 0.1}),
)


def main(*, repeats: int = 3) -> None:
    """Print the best of `repeats` wall-clock build times of each case."""
    for name, kwargs in CASES:
        best = float("inf")
        for _ in range(repeats):
            start = time.perf_counter()
            mdp = grid_mdp(gamma=0.95, **kwargs)  # type: ignore[arg-type]
            best = min(best, time.perf_counter() - start)
        print(f"{name:45s} {mdp.n_states:>7,} states × {mdp.n_actions} actions  {best * 1000:8.1f} ms")


if __name__ == "__main__":
    main()
