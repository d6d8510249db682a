"""What `metairl demo` writes: the paper-style Pearson-vs-tasks figure, reward heatmaps, tables, results files.

matplotlib is used through `matplotlib.figure.Figure` and the Agg canvas (no pyplot state, no display).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from metairl_cli.demo_experiment import DemoSettings, JobOutcome, SimWorld, tasks_label
from service.files.images import heatmap_png

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FIGURE_FILE = "pearson_vs_tasks.png"
HEATMAP_FILES = {
    "true": "heatmap_true.png",
    "learned": "heatmap_learned.png",
    "baseline": "heatmap_baseline.png",
}
SHOWCASE_LOSS = "huber"
"""The loss whose rewards the heatmaps show when it was run (the paper's best); else any loss with sharing."""


@dataclass(frozen=True)
class Summary:
    """Accuracy of one (loss, task count) cell: mean ± sd over ``n`` worlds of each world's mean task Pearson.

    The same statistic as benchmarks/accuracy.py (population sd over worlds), so the full demo's table
    can be read against the committed benchmark.
    """

    loss: str
    n_tasks: int
    mean: float
    sd: float
    n: int
    baseline_mean: float


def summarize(outcomes: Sequence[JobOutcome]) -> list[Summary]:
    """One `Summary` per (loss, task count) that has at least one succeeded job, in first-seen order."""
    cells: dict[tuple[str, int], list[JobOutcome]] = {}
    for outcome in outcomes:
        if outcome.succeeded:
            cells.setdefault((outcome.plan.loss, outcome.plan.n_tasks), []).append(outcome)
    out = []
    for (loss, n_tasks), group in cells.items():
        per_world = np.array([np.mean(o.pearsons) for o in group])
        baselines = [o.baseline_pearson for o in group if o.baseline_pearson is not None]
        out.append(
            Summary(
                loss=loss,
                n_tasks=n_tasks,
                mean=float(per_world.mean()),
                sd=float(per_world.std()),
                n=len(group),
                baseline_mean=float(np.mean(baselines)),
            )
        )
    return out


def pearson_figure(
    summaries: Sequence[Summary], *, losses: Sequence[str], task_counts: Sequence[int]
) -> Figure:
    """Mean Pearson (goal excluded) vs number of tasks, one error-bar line (± 1 sd) per loss with results."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.4), dpi=100, layout="constrained")
    ax = fig.add_subplot()
    drawn = [loss for loss in losses if any(s.loss == loss for s in summaries)]
    for i, loss in enumerate(drawn):
        points = sorted((s for s in summaries if s.loss == loss), key=lambda s: s.n_tasks)
        shift = 2 ** (0.03 * (i - (len(drawn) - 1) / 2))  # side by side, so error bars do not hide each other
        ax.errorbar(
            [s.n_tasks * shift for s in points],
            [s.mean for s in points],
            yerr=[s.sd for s in points],
            marker="o",
            capsize=3,
            label=loss,
        )
    ax.set_xscale("log", base=2)
    ax.set_xticks(list(task_counts), [str(k) for k in task_counts])
    ax.minorticks_off()
    ax.set_xlabel("number of tasks")
    ax.set_ylabel("Pearson r with the true reward (goal excluded)")
    ax.set_title("Reward accuracy by sharing loss (mean ± sd over worlds)")
    ax.grid(alpha=0.3)
    if drawn:
        ax.legend(title="sharing loss")
    return fig


def markdown_table(
    summaries: Sequence[Summary], *, losses: Sequence[str], task_counts: Sequence[int], baseline: bool = False
) -> str:
    """Losses as rows and task counts as columns: ``mean ± sd`` of task rewards, or the baseline's mean."""
    cells = {(s.loss, s.n_tasks): s for s in summaries}

    def cell(loss: str, k: int) -> str:
        s = cells.get((loss, k))
        if s is None:
            return "—"
        return f"{s.baseline_mean:.3f}" if baseline else f"{s.mean:.3f} ± {s.sd:.3f}"

    header = "| loss | " + " | ".join(tasks_label(k) for k in task_counts) + " |"
    rule = "| --- |" + " --- |" * len(task_counts)
    rows = [f"| {loss} | " + " | ".join(cell(loss, k) for k in task_counts) + " |" for loss in losses]
    return "\n".join([header, rule, *rows])


def showcase(outcomes: Sequence[JobOutcome]) -> JobOutcome | None:
    """The job whose rewards the heatmaps show: world 0, most tasks, preferring `SHOWCASE_LOSS`, then sharing."""
    candidates = [o for o in outcomes if o.succeeded and o.plan.world == 0]
    if not candidates:
        return None
    return max(
        candidates, key=lambda o: (o.plan.n_tasks, o.plan.loss == SHOWCASE_LOSS, o.plan.loss != "none")
    )


def write_heatmaps(out: Path, sim: SimWorld, outcome: JobOutcome) -> list[Path]:
    """Heatmaps of task 0 of ``sim``: true reward (with its demonstrations), learned reward, and the baseline."""
    assert outcome.rewards is not None and outcome.baseline is not None
    layout = sim.world.mdp.layout
    assert layout is not None
    task = sim.tasks[0]
    how = f"{outcome.plan.loss}, {tasks_label(outcome.plan.n_tasks)}"
    images = {
        "true": heatmap_png(
            task.true_reward,
            layout=layout,
            title=f"True reward, {task.name}",
            trajectories=[t.states for t in task.trajectories],
        ),
        "learned": heatmap_png(
            outcome.rewards[0],
            layout=layout,
            title=f"Learned ({how}), r={outcome.pearsons[0]:.2f}",
        ),
        "baseline": heatmap_png(
            outcome.baseline,
            layout=layout,
            title=f"Baseline ({how}), r={outcome.baseline_pearson:.2f}",
        ),
    }
    paths = []
    for key, png in images.items():
        path = out / HEATMAP_FILES[key]
        path.write_bytes(png)
        paths.append(path)
    return paths


def write_report(
    out: Path, settings: DemoSettings, worlds: Sequence[SimWorld], outcomes: Sequence[JobOutcome]
) -> str:
    """Write figure, heatmaps, results.md and results.json into ``out``; returns the accuracy table (markdown)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    out.mkdir(parents=True, exist_ok=True)
    summaries = summarize(outcomes)
    losses, task_counts = settings.losses, settings.task_counts
    figure = pearson_figure(summaries, losses=losses, task_counts=task_counts)
    FigureCanvasAgg(figure).print_png(out / FIGURE_FILE)
    shown = showcase(outcomes)
    if shown is not None:
        write_heatmaps(out, worlds[0], shown)
    table = markdown_table(summaries, losses=losses, task_counts=task_counts)
    baseline_table = markdown_table(summaries, losses=losses, task_counts=task_counts, baseline=True)
    failed = [o for o in outcomes if not o.succeeded]
    (out / "results.md").write_text(_markdown(settings, table, baseline_table, failed, shown))
    (out / "results.json").write_text(json.dumps(_json(settings, summaries, outcomes), indent=2) + "\n")
    return table


def _markdown(
    settings: DemoSettings,
    table: str,
    baseline_table: str,
    failed: Sequence[JobOutcome],
    shown: JobOutcome | None,
) -> str:
    """results.md: what was run, the two tables, links to the pictures and any failed jobs."""
    lines = [
        "# metairl demo: terrain path planning (Li & Burdick §IV-A)",
        "",
        f"{settings.n_worlds} worlds of {settings.size}×{settings.size} cells ({settings.n_hills} hills), "
        f"{settings.n_tasks} goal tasks per world, {settings.n_demos} demonstrations per task, "
        f"max_steps {settings.max_steps}, seed {settings.seed}.",
        "",
        "## Pearson r of each learned task reward with its true reward (goal state excluded), mean ± sd over worlds",
        "",
        table,
        "",
        "## Pearson r of the learned baseline with the terrain's −cost, mean",
        "",
        baseline_table,
        "",
        f"![Pearson r vs number of tasks]({FIGURE_FILE})",
    ]
    if shown is not None:
        lines += [
            "",
            "## Rewards of world 0, task 0",
            "",
            f"The true reward with its demonstrations, then the task reward and the baseline learned by job "
            f"{shown.job_id} ({shown.plan.describe()}); r is the Pearson correlation with the true reward "
            "(goal excluded), for the baseline with the terrain's −cost.",
            "",
        ]
        lines += [f"![{key}]({name})" for key, name in HEATMAP_FILES.items()]
    if failed:
        lines += ["", "## Jobs that did not succeed", ""]
        lines += [f"- {o.job_id} ({o.plan.describe()}): {o.status}, {o.error}" for o in failed]
    return "\n".join(lines) + "\n"


def _json(
    settings: DemoSettings, summaries: Sequence[Summary], outcomes: Sequence[JobOutcome]
) -> dict[str, Any]:
    """results.json: settings, one summary per (loss, task count) and every job with ids and scores."""
    return {
        "settings": asdict(settings) | {"n_tasks": settings.n_tasks},
        "summary": [asdict(s) for s in summaries],
        "jobs": [o.to_json() for o in outcomes],
    }
