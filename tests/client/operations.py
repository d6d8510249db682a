"""Which client methods call each operation of the API's OpenAPI document, and the client's coverage.

``python -m tests.client.operations`` prints the coverage of the app as built here (operations with a
method / all operations) and names any operation without one.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

OPERATION_METHODS: dict[str, tuple[str, ...]] = {
    "healthz_healthz_get": ("check_health",),
    "readyz_readyz_get": ("check_ready",),
    "create_mdp_v1_mdps_post": ("create_mdp", "upload_mdp"),
    "list_mdps_v1_mdps_get": ("list_mdps", "iter_mdps"),
    "get_mdp_v1_mdps__mdp_id__get": ("get_mdp",),
    "delete_mdp_v1_mdps__mdp_id__delete": ("delete_mdp",),
    "get_mdp_arrays_v1_mdps__mdp_id__arrays_get": ("mdp_arrays",),
    "create_demonstrator_v1_demonstrators_post": ("create_demonstrator",),
    "list_demonstrators_v1_demonstrators_get": ("list_demonstrators", "iter_demonstrators"),
    "get_demonstrator_v1_demonstrators__demonstrator_id__get": ("get_demonstrator",),
    "delete_demonstrator_v1_demonstrators__demonstrator_id__delete": ("delete_demonstrator",),
    "create_task_v1_demonstrators__demonstrator_id__tasks_post": ("create_task",),
    "list_tasks_v1_demonstrators__demonstrator_id__tasks_get": ("list_tasks", "iter_tasks"),
    "get_task_v1_tasks__task_id__get": ("get_task",),
    "delete_task_v1_tasks__task_id__delete": ("delete_task",),
    "put_true_reward_v1_tasks__task_id__true_reward_put": ("put_true_reward",),
    "get_true_reward_v1_tasks__task_id__true_reward_get": ("get_true_reward",),
    "add_demonstrations_v1_tasks__task_id__demonstrations_post": (
        "add_demonstrations",
        "upload_demonstrations",
    ),
    "list_demonstrations_v1_tasks__task_id__demonstrations_get": (
        "list_demonstrations",
        "iter_demonstrations",
    ),
    "read_batch_v1_tasks__task_id__demonstrations__batch_id__get": (
        "get_demonstrations",
        "download_demonstrations",
    ),
    "delete_batch_v1_tasks__task_id__demonstrations__batch_id__delete": ("delete_demonstrations",),
    "upload_recording_v1_demonstrators__demonstrator_id__recordings_post": ("upload_recording",),
    "list_recordings_v1_demonstrators__demonstrator_id__recordings_get": (
        "list_recordings",
        "iter_recordings",
    ),
    "recording_demonstrations_v1_recordings__recording_id__demonstrations_get": ("recording_demonstrations",),
    "submit_job_v1_jobs_post": ("submit_job",),
    "list_jobs_v1_jobs_get": ("list_jobs", "iter_jobs"),
    "read_job_v1_jobs__job_id__get": ("get_job",),
    "delete_job_v1_jobs__job_id__delete": ("delete_job",),
    "list_events_v1_jobs__job_id__events_get": ("list_events", "iter_events", "wait"),
    "read_history_v1_jobs__job_id__history_get": ("job_history",),
    "cancel_job_v1_jobs__job_id__cancel_post": ("cancel_job",),
    "job_rewards_v1_jobs__job_id__rewards_get": ("job_rewards", "rewards"),
    "download_reward_v1_rewards__reward_id__get": ("reward_values", "download_reward", "reward_png"),
    "create_comparison_v1_comparisons_post": ("compare",),
    "comparison_matrix_v1_jobs__job_id__comparison_matrix_get": (
        "comparison_matrix",
        "comparison_matrix_png",
    ),
    "key_states_v1_rewards__reward_id__key_states_get": ("key_states",),
    "motion_summary_v1_demonstrators__demonstrator_id__motion_summary_get": ("motion_summary",),
    "recording_sway_route_v1_recordings__recording_id__sway_get": ("recording_sway", "recording_sway_png"),
    "demonstrator_sway_summary_v1_demonstrators__demonstrator_id__sway_summary_get": ("sway_summary",),
    "motion_comparison_v1_motion_comparisons_post": ("compare_motion", "compare_motion_png"),
    "create_webhook_v1_webhooks_post": ("create_webhook",),
    "list_webhooks_v1_webhooks_get": ("list_webhooks", "iter_webhooks"),
    "read_webhook_v1_webhooks__webhook_id__get": ("get_webhook",),
    "delete_webhook_v1_webhooks__webhook_id__delete": ("delete_webhook",),
}
"""operationId → the client methods that call it (the first is the plain one)."""

NOT_OPERATIONS = frozenset({"connect", "close", "with_options"})
"""Public methods of the clients that call no operation."""


def operations(spec: dict[str, Any]) -> dict[str, str]:
    """Every operation of an OpenAPI document: operationId → ``METHOD /path``."""
    return {
        operation["operationId"]: f"{method.upper()} {path}"
        for path, item in spec["paths"].items()
        for method, operation in item.items()
        if isinstance(operation, dict) and "operationId" in operation
    }


def missing_operations(spec: dict[str, Any]) -> list[str]:
    """``METHOD /path (operationId)`` of each operation that no client method calls."""
    return sorted(f"{route} ({op})" for op, route in operations(spec).items() if op not in OPERATION_METHODS)


def coverage_line(spec: dict[str, Any]) -> str:
    """``client coverage: 39/39 operations have a method``, and the missing ones below."""
    every = operations(spec)
    missing = missing_operations(spec)
    lines = [f"client coverage: {len(every) - len(missing)}/{len(every)} operations have a method"]
    return "\n".join(lines + [f"  no method: {m}" for m in missing])


def main() -> None:
    """Print the coverage of the app on a throwaway SQLite database."""
    from service.api.app import create_app
    from service.settings import Settings

    with tempfile.TemporaryDirectory() as folder:
        data = Path(folder)
        app = create_app(Settings(data_dir=data / "var", database_url=f"sqlite:///{data / 'metairl.db'}"))
        print(coverage_line(app.openapi()))
        app.state.engine.dispose()


if __name__ == "__main__":
    main()
