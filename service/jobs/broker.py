"""Celery broker configuration shared by the API (which only sends) and the worker (which consumes).

Both sides must agree on the URL and transport options, so they are computed here from `Settings`:
the embedded default is Celery's ``filesystem://`` transport with absolute folders under ``data_dir``;
Redis gets a visibility timeout, and RabbitMQ a consumer timeout, longer than the longest job so a running
job's unacknowledged message is neither redelivered nor cut off while it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from kombu import Connection, Exchange, Queue

from service.settings import Settings

TASK_NAME = "metairl.run_job"
"""The Celery task that runs one job; the API sends it by this name (it never imports the worker)."""


EMBEDDED_BROKER_URL = "filesystem://localhost//"
"""The embedded broker, Celery's ``filesystem://`` transport, with its host named: without one kombu warns, at
each worker start, that it assumes ``localhost``."""


def broker_url(settings: Settings) -> str:
    """The configured broker URL, or the embedded ``filesystem://`` broker."""
    return settings.broker_url or EMBEDDED_BROKER_URL


def broker_folder(settings: Settings) -> Path:
    """The absolute folder of the embedded filesystem broker (messages and exchange tables)."""
    return (settings.data_dir / "broker").resolve()


def unacked_timeout_s(settings: Settings) -> int:
    """How long a delivered, unacknowledged message is left with its worker: an hour above the hard time limit."""
    return settings.job_time_limit_s + 3600


def is_amqp(settings: Settings) -> bool:
    """Whether the broker is RabbitMQ (an ``amqp://`` or ``pyamqp://`` URL, with or without TLS)."""
    return broker_url(settings).startswith(("amqp://", "amqps://", "pyamqp://"))


def transport_options(settings: Settings) -> dict[str, Any]:
    """Kombu transport options for the configured broker (creating the filesystem folders if needed)."""
    url = broker_url(settings)
    if url.startswith("filesystem://"):
        root = broker_folder(settings)
        queue, control = root / "queue", root / "control"
        for folder in (queue, control):
            folder.mkdir(parents=True, exist_ok=True)
        return {
            "data_folder_in": str(queue),
            "data_folder_out": str(queue),
            "control_folder": str(control),
            "polling_interval": 0.5,
        }
    if url.startswith(("redis://", "rediss://")):
        # Unacked messages come back after this long: it must exceed the longest job (hard time limit).
        return {"visibility_timeout": unacked_timeout_s(settings)}
    if is_amqp(settings):
        # Publisher confirms: a send returns only once RabbitMQ has taken the message (else it raises).
        return {"confirm_publish": True}
    return {}


def job_queue(settings: Settings) -> Queue:
    """The durable queue jobs travel on; on RabbitMQ its consumer timeout exceeds the longest job.

    RabbitMQ closes a channel whose delivery stays unacknowledged longer than ``consumer_timeout``
    (30 min by default); with late acks a job holds its message for its whole run. RabbitMQ 3.12+ reads
    the per-queue ``x-consumer-timeout``; older servers ignore it and need ``consumer_timeout`` raised.
    """
    arguments = {"x-consumer-timeout": unacked_timeout_s(settings) * 1000} if is_amqp(settings) else None
    name = settings.queue_name
    return Queue(name, Exchange(name, type="direct"), routing_key=name, queue_arguments=arguments)


def delete_queue(settings: Settings) -> None:
    """Remove the job queue and its exchange from a configured broker (tests and benchmarks with their own
    queue on a shared server; the embedded broker goes with its data folder). On Redis the queue is declared
    first: kombu deletes only the bindings its channel knows of, so a fresh channel would leave them behind."""
    if settings.broker_url:
        with Connection(settings.broker_url) as broker:
            queue = job_queue(settings)(broker.default_channel)
            queue.declare()
            queue.delete()
            queue.exchange.delete()


def celery_config(settings: Settings) -> dict[str, Any]:
    """The Celery settings both sides use to reach the broker (no result backend: results go to the database)."""
    return {
        "broker_url": broker_url(settings),
        "broker_transport_options": transport_options(settings),
        "broker_connection_retry_on_startup": True,
        "task_default_queue": settings.queue_name,
        "task_queues": [job_queue(settings)],
        "task_ignore_result": True,
        "task_serializer": "json",
        "accept_content": ["json"],
    }
