"""Write benchmarks/RESULTS.md from the benchmarks' stored result files: one section per question, each table
with the command, machine and versions that made its rows. ``--check`` fails when the page differs. Usage::

    python -m benchmarks.results            # rewrite benchmarks/RESULTS.md
    python -m benchmarks.results --check    # exit 1 if the committed page is not what the files give
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import ablation, accuracy, uncertainty, versus

HERE = Path(__file__).resolve().parent
PAGE = HERE / "RESULTS.md"
FAMILIES = HERE / "FAMILIES.md"
"""Another benchmark's page of accuracy per benchmark family; included when it exists."""
GRID_ENGINE = "baddbmm-step"
"""The engine the stored path-planning grid ran on (`accuracy.ENGINE` documents the names)."""
BEFORE_ENGINE = "stays-at-ends"
"""The engine before today's, whose terrain ablation rows the accuracy section compares with."""
UNRECORDED = "not recorded"


def load(name: str) -> Any:
    """A stored result file of this folder, or None when it does not exist."""
    path = HERE / name
    return json.loads(path.read_text()) if path.exists() else None


def provenance_lines(runs: list[dict[str, Any] | None], commands: list[str]) -> list[str]:
    """Markdown lines saying what made a table: its commands, then per distinct run its machine and versions;
    rows stored without a record say so."""
    lines = ["```bash", *commands, "```", ""]
    seen: list[dict[str, Any] | None] = []
    for run in runs:
        if run not in seen:
            seen.append(run)
    for run in seen:
        if run is None:
            lines.append(
                "- **Provenance not recorded**: these rows came from an earlier machine before the benchmarks "
                "stored their command, machine and versions."
            )
            continue
        machine, versions = run.get("machine", {}), run.get("versions", {})
        cpu = machine.get("cpu", UNRECORDED)
        cores = machine.get("cores")
        threads = machine.get("torch_threads")
        hardware = f"{cpu}, {cores} cores" if cores else cpu
        if machine.get("usable_cores") not in (None, cores):
            hardware += f" ({machine['usable_cores']} usable)"
        if threads:
            hardware += f", {threads} torch thread{'s' if threads > 1 else ''}"
        if machine.get("load_average") is not None:
            hardware += f", load average {machine['load_average']}"
        stack = ", ".join(f"{k} {v}" for k, v in versions.items()) or UNRECORDED
        lines.append(
            f"- Ran `{run.get('command', UNRECORDED)}` on {run.get('date') or 'an unrecorded date'}."
        )
        lines.append(f"- Machine: {hardware}. Versions: {stack}.")
        if run.get("served"):
            lines.append(f"- Served: {run['served']}.")
        if run.get("engine_commit"):
            lines.append(f"- Engine timed: commit {run['engine_commit']}.")
        if run.get("note"):
            lines.append(f"- Note: {run['note']}.")
    return lines


def machines(rows: list[dict[str, Any]]) -> set[str]:
    """The processors ``rows`` ran on, as their provenance names them (a carried row: where it first ran)."""
    return {r["provenance"]["machine"].get("cpu", UNRECORDED) for r in rows if r.get("provenance")}


def accuracy_section() -> list[str]:
    """Accuracy per family: the terrain generators (default against no sharing), other families, the grid."""
    rows = [
        r for r in load("ablation_results.json") or [] if r["config_key"].startswith(f"{accuracy.ENGINE}:")
    ]
    labels = list(dict.fromkeys(r["variant"] for r in rows))
    out = [
        "## Accuracy per family",
        "",
        "### Terrain generators: today's default against no sharing",
        "",
        "8 tasks × 3 demonstrations, goal state excluded, 10 worlds each of the repo's generator "
        "(`metairl_engine/sim/terrain.py`, tuned on), the frozen generator (`benchmarks/frozen_terrain.py`, never "
        "tuned on) and the slip generator (the repo's worlds with moves that slip with probability "
        f"{ablation.SLIP}, never tuned on). Cells: Pearson of each task's learned reward with its true reward, "
        "mean ± std over worlds; the baseline column compares the learned baseline with −cost. "
        '"(no features)" fits the same MDPs uploaded without features or layout.',
        "",
        *provenance_lines(
            [r.get("provenance") for r in rows],
            [
                "python -m benchmarks.ablation --variants default none",
                "python -m benchmarks.ablation --featureless --variants default",
                "python -m benchmarks.ablation --table --all   # prints this table from the cache",
            ],
        ),
        "",
        ablation.table(rows, labels),
        "",
    ]
    gains = []
    for g in ablation.GENERATORS:
        mean = {
            v: np.mean([r["task_pearson"] for r in rows if r["variant"] == v and r["generator"] == g])
            for v in ("default", "none")
        }
        gains.append(f"{g} {mean['default'] - mean['none']:+.3f}")
    out += [f"Sharing gain (default − none): {', '.join(gains)}.", ""]
    before = [
        r for r in load("ablation_results.json") or [] if r["config_key"].startswith(f"{BEFORE_ENGINE}:")
    ]
    changes = []
    for v in dict.fromkeys(
        r["variant"] for r in before if r["variant"] in labels and not r["variant"].startswith("none")
    ):
        for g in ablation.GENERATORS:
            old = {r["world"]: r["task_pearson"] for r in before if r["variant"] == v and r["generator"] == g}
            new = {r["world"]: r["task_pearson"] for r in rows if r["variant"] == v and r["generator"] == g}
            paired = [new[w] - old[w] for w in sorted(old.keys() & new.keys())]
            if len(paired) > 1:
                se = np.std(paired, ddof=1) / np.sqrt(len(paired))
                changes.append(
                    f"{v}, {g} {np.mean(list(old.values())):.3f} → {np.mean(list(new.values())):.3f} "
                    f"({np.mean(paired):+.3f} ± {se:.3f})"
                )
    if changes:
        elsewhere = not machines(before) & machines([r for r in rows if "carried_from" not in r])
        out += [
            f"Against the engine before (`{BEFORE_ENGINE}`, where the baseline learned from a task's reward one move "
            "from its visits as on a visit; its rows stay in the cache): before → today, and the change paired "
            "by world "
            f"± its standard error: {'; '.join(changes)}."
            + (
                " The engine before's rows ran on another machine, whose fits differ by up to about ±0.02 "
                "per world."
                if elsewhere
                else ""
            ),
            "",
        ]
    if FAMILIES.exists():
        text = FAMILIES.read_text()
        body = text.split("\n", 1)[1] if text.startswith("# ") else text  # its title becomes ours
        out += ["### Benchmark families", "", "From [FAMILIES.md](FAMILIES.md):", ""]
        out += [re.sub(r"^(#+) ", r"\1## ", line) for line in body.strip("\n").splitlines()] + [""]
    grid = [r for r in load("accuracy_results.json") or [] if r["engine"] == GRID_ENGINE]
    out += [
        "### The paper's path-planning grid (§IV-A, Fig. 2)",
        "",
        "The repo's generator, 10 worlds × tasks 1, 2, 4, 8, 16 × demonstrations 1, 3, 10 × the five sharing "
        f"losses ({len(grid)} fits, one thread). These rows ran on the `{GRID_ENGINE}` engine, an earlier one: the "
        "method of `cheap-step` (no sparse task deviations) with the step before its cheaper rewrite "
        "(`benchmarks/accuracy.py`, `ENGINE`).",
        "",
        *provenance_lines(
            [r.get("provenance") for r in grid],
            [
                "python -m benchmarks.accuracy   # runs what the cache lacks on today's engine",
                f"python -m benchmarks.accuracy --engine {GRID_ENGINE} --plot benchmarks/accuracy.png",
                f"python -m benchmarks.accuracy --engine {GRID_ENGINE} --tasks 8 --demos 1 3 10 "
                "--plot benchmarks/accuracy_demos.png",
            ],
        ),
        "",
        accuracy.summarise(grid),
        "",
        "![Pearson with the true reward against the number of tasks](accuracy.png)",
        "",
        "![Pearson with the true reward against demonstrations per task, 8 tasks](accuracy_demos.png)",
        "",
    ]
    return out


def fit_time_section() -> list[str]:
    """Time per default fit on both terrain generators, from the last `fit_time` run."""
    stored = load("fit_time_results.json")
    out = ["## Time per fit", ""]
    if stored is None:
        return [*out, "No stored run: `python -m benchmarks.fit_time` makes one.", ""]
    rows = stored["rows"]
    out += [
        "One default fit (8 tasks × 3 demonstrations) per world, one torch thread, CPU seconds of the fit alone; "
        "run it from a checkout of another commit to compare engines (its docstring says how). Wall seconds grow "
        "with the machine's load (recorded below); CPU seconds much less.",
        "",
        *provenance_lines([stored["provenance"]], [stored["provenance"]["command"]]),
        "",
        "| generator | worlds | CPU s per fit | wall s per fit | steps | Pearson, goal excluded |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for g in dict.fromkeys(r["generator"] for r in rows):
        sel = [r for r in rows if r["generator"] == g]
        out.append(
            f"| {g} | {len(sel)} | {np.mean([r['cpu_seconds'] for r in sel]):.1f} "
            f"| {np.mean([r['seconds'] for r in sel]):.1f} | {np.mean([r['steps'] for r in sel]):.0f} "
            f"| {np.mean([r['task_pearson'] for r in sel]):.3f} |"
        )
    return [*out, ""]


def scale_section() -> list[str]:
    """The 80,000-state motion MDP: step time, a fit to the stopping rule, peak memory."""
    stored = load("scale_results.json")
    out = ["## Scale: 80,000 states", ""]
    if stored is None:
        return [*out, "No stored run: `python -m benchmarks.scale` makes one.", ""]
    out += [
        "The paper's 100×100 grid × 8 velocity directions (80,000 states, 8 actions), Huber sharing on all states "
        "(automatic sharing blocks), MLP [100, 50, 25], 3 soft-optimal demonstrations per task; each measurement "
        "in a fresh process, so peak RSS is that fit's (with ~0.3 GB of interpreter, torch and demonstration "
        "generation). Step time: median over the steps after a warm-up. Wall seconds grow with the machine's load "
        "(recorded below); CPU seconds much less.",
        "",
        *provenance_lines([stored["provenance"]], [stored["provenance"]["command"]]),
        "",
        "| measurement | tasks | wall s/step (CPU s/step) | wall s per task-step | steps (kept) | wall s "
        "| Pearson all (visited) | peak RSS GB |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in stored["rows"]:
        if r["measurement"] == "step time":
            cells = [
                f"{r['s_per_step']:.3f} ({r['cpu_s_per_step']:.3f})",
                f"{r['s_per_task_step']:.3f}",
                "",
                "",
            ]
            cells.append("")
        elif r["measurement"] == "to stopping rule":
            cells = ["", "", f"{r['steps']} ({r['kept_step']})", f"{r['wall_s']:.0f}"]
            cells.append(f"{r['pearson_all']:.3f} ({r['pearson_visited']:.3f})")
        else:
            cells = ["", f"{r['s_per_task']:.1f} s per task", f"{r['iterations']} iterations", "", ""]
        out.append(f"| {r['measurement']} | {r['tasks']} | {' | '.join(cells)} | {r['peak_rss_gb']:.2f} |")
    return [*out, ""]


def comparisons_section() -> list[str]:
    """A job's comparison matrix in the API process: seconds and memory on velocity grids up to 80,000 states."""
    stored = load("comparisons_results.json")
    out = ["## Comparison matrix: EPIC with dynamics in the API process", ""]
    if stored is None:
        return [*out, "No stored run: `python -m benchmarks.comparisons` makes one.", ""]
    out += [
        "EPIC with dynamics between every pair of k rewards (a job of k − 1 tasks and its baseline), what "
        "`GET /v1/jobs/{id}/comparison-matrix` computes: each reward canonicalised by a conjugate-gradient solve, "
        'all k in lockstep (docs/architecture.md, "Canonicalising rewards"). Each case in a fresh process; '
        "memory is its peak resident size above what the process held before (the MDP and rewards built), the "
        "request's share of the API's memory (`METAIRL_API_MAX_REQUEST_MEMORY_MB` is 512 by default).",
        "",
        *provenance_lines([stored["provenance"]], [stored["provenance"]["command"]]),
        "",
        "| velocity grid | states | γ | rewards | wall s | CPU s | memory added MiB |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in stored["rows"]:
        out.append(
            f"| {r['size']}×{r['size']} × 8 | {r['states']:,} | {r['gamma']} | {r['rewards']} | {r['wall_s']:.1f} "
            f"| {r['cpu_s']:.1f} | {r['added_mib']:.0f} |"
        )
    return [*out, ""]


def load_section() -> list[str]:
    """API throughput and latency under wrk, from the last `load` run."""
    stored = load("load_results.json")
    out = ["## API load", ""]
    if stored is None:
        return [*out, "No stored run: `python -m benchmarks.load` makes one.", ""]
    out += [
        "`uvicorn --factory service.api.app:create_app --workers 2` on loopback against PostgreSQL with Redis "
        "(`postgres`) and the embedded SQLite with the `filesystem://` broker (`sqlite`); a lab, its key and a "
        "succeeded job with an 80,000-value baseline reward and a 100,000-step loss curve (the longest a fit "
        "keeps); `wrk -t2`, medians of 3 runs of 5 s.",
        "",
        *provenance_lines([stored["provenance"]], [stored["provenance"]["command"]]),
        "",
        "| backend | request | conns | req/s | p50 ms | p99 ms | non-2xx |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in stored["rows"]:
        out.append(
            f"| {r['backend']} | `{r['request']}` | {r['connections']} | {r['rps']:,.0f} | {r['p50_ms']:.1f} "
            f"| {r['p99_ms']:.1f} | {r['non_2xx']} |"
        )
    rss = "; ".join(f"{b} {', '.join(f'{mb:.0f}' for mb in v['after'])}" for b, v in stored["rss_mb"].items())
    return [*out, "", f"API worker RSS after the load, MB per process: {rss}.", ""]


def versus_section() -> list[str]:
    """This engine against imitation's MCE IRL on the same MDPs."""
    rows = load("versus_results.json")
    out = ["## Versus imitation's MCE IRL", ""]
    if rows is None:
        return [*out, "No stored run: `python -m benchmarks.versus` makes one.", ""]
    out += [
        "The same MDPs and demonstrations (4 tasks × 3 demonstrations a world) for this engine's default, the "
        "default stopped after at most N steps, its `maxent` reference solver and imitation 1.0.1's "
        "finite-horizon MCE IRL (dense transitions, reward net [100, 50, 25] on the same features; settings in "
        "`benchmarks/versus.py`'s docstring). imitation runs in its own venv, `.venv-imitation`.",
        "",
        *provenance_lines(
            [r.get("provenance") for r in rows],
            [
                'python3 -m venv .venv-imitation && .venv-imitation/bin/pip install "torch==2.13.0" '
                '"imitation==1.0.1"',
                "OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.versus "
                "--sizes 10000 80000",
                "OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python -m benchmarks.versus "
                "--sizes 1000 --capped-steps 10 20 40",
            ],
        ),
        "",
        versus.table(rows),
        "",
        "At 10,000 states (one 100×100 world, 4 tasks × 3 demonstrations) no reward is learned: one hill per "
        "~43 cells makes the cost vary from cell to cell, while the twelve demonstrations visit a few hundred "
        "of the 10,000 cells, so what the networks extrapolate from the coordinates is uncorrelated with the "
        "terrain (every task within ±0.04, with or without the task deviations made sparse). The row shows the "
        "engine's time at that size, not accuracy.",
        "",
    ]
    return out


def uncertainty_section() -> list[str]:
    """Does the reward's spread across the ensemble's members say where the reward is wrong, per family."""
    stored = load("uncertainty_results.json")
    out = ["## Uncertainty per state", ""]
    if stored is None:
        return [*out, "No stored run: `python -m benchmarks.uncertainty` makes one.", ""]
    out += [
        "One default fit per world (terrain: 8 tasks × 3 demonstrations; multi-task families: 8 goal tasks × 3; "
        "objectworld: 16 paths of 8 steps), and a second of another seed. Each learned reward is put on its true "
        "reward's scale by a least-squares affine fit; Spearman correlations are pooled over every task's "
        "states but its goal. Spread: `FitResult.reward_spread`; hops: moves to the nearest state the task's "
        "demonstrations visit; baseline: its spread against its error w.r.t. the world's reward (terrain: "
        "−cost). Abs(truth − mean) is no estimate (it needs the truth): it is what ranks the error where the "
        "learned reward explains little of the truth. The best function of the reward: the error's mean per decile "
        "of each task's standardised learned reward, chosen with the truth on the same states (a bound on any "
        "estimate read off the reward alone), and the decile where it peaks, per world. The refit columns: how far the spread ranks the "
        "difference between the two fits, and how far the two fits' errors rank alike. The frozen families "
        'are only reported. docs/method.md, "Uncertainty per state", reads the table.',
        "",
        *provenance_lines([stored["provenance"]], [stored["provenance"]["command"]]),
        "",
        uncertainty.table(stored["rows"]),
        "",
    ]
    return out


def page() -> str:
    """The whole of RESULTS.md."""
    lines = [
        "# Benchmark results",
        "",
        "Written by `python -m benchmarks.results` from the stored result files (`benchmarks/*_results.json`, "
        "and `benchmarks/FAMILIES.md` when present); edit those or rerun a benchmark, not this page "
        "(`tests/test_benchmark_results.py` fails when they disagree). Each table names the command that made "
        "its rows and the machine and versions it ran on. The motion benchmarks have their own page, "
        "[MOTION.md](MOTION.md).",
        "",
        *accuracy_section(),
        *fit_time_section(),
        *scale_section(),
        *comparisons_section(),
        *load_section(),
        *versus_section(),
        *uncertainty_section(),
    ]
    return "\n".join(lines).rstrip("\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write the page, or with ``--check`` compare it with the committed one."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if RESULTS.md differs from the files")
    args = parser.parse_args(argv)
    text = page()
    if args.check:
        if PAGE.read_text() != text:
            print("benchmarks/RESULTS.md is stale: run python -m benchmarks.results", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
