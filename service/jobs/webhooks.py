"""Webhooks on job end (docs/api.md, "Webhooks"): the events, the targets allowed, the Standard Webhooks
signature, and the delivery rows written with a job's final status.

`notify_job_end` is called by `service.jobs.transitions.transition` inside the transaction that records the
final status, so a delivery exists exactly when the ending was committed. The workers send deliveries
(`worker.webhooks`); nothing here makes a network call except `check_target`'s name lookup.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import ipaddress
import secrets
import socket
from datetime import timedelta
from urllib.parse import urlsplit

from sqlalchemy import select
from sqlalchemy.orm import Session

from service.jobs.status import JobStatus
from service.store.ids import new_id
from service.store.models.jobs import Job
from service.store.models.webhooks import Webhook, WebhookDelivery

EVENTS = ("job.succeeded", "job.failed", "job.cancelled")
"""The event types a webhook can subscribe to (contract)."""
SECRET_PREFIX = "whsec_"
MAX_BACKOFF = timedelta(hours=1)


def event_type(status: JobStatus) -> str:
    """The event type of a job reaching a final status: ``job.<status>``."""
    return f"job.{status.value}"


def new_secret() -> str:
    """A signing secret as the spec writes it: ``whsec_`` + base64 of 32 random bytes."""
    return SECRET_PREFIX + base64.b64encode(secrets.token_bytes(32)).decode()


def sign(secret: str, *, msg_id: str, timestamp: int, body: bytes) -> str:
    """The ``webhook-signature`` value: ``v1,`` + base64 HMAC-SHA256 of ``{id}.{timestamp}.{body}``."""
    key = base64.b64decode(secret.removeprefix(SECRET_PREFIX))
    signed = f"{msg_id}.{timestamp}.".encode() + body
    return "v1," + base64.b64encode(hmac.new(key, signed, hashlib.sha256).digest()).decode()


def backoff(attempts: int, first_s: float) -> timedelta:
    """The wait after the ``attempts``-th failed attempt: ``first_s`` doubled each time, at most an hour."""
    return min(timedelta(seconds=first_s * 2 ** max(0, attempts - 1)), MAX_BACKOFF)


def private_address(address: str) -> bool:
    """Whether an IP address is one a service must not call for strangers (private, loopback, link-local …)."""
    ip = ipaddress.ip_address(address)
    return not ip.is_global or ip.is_multicast


def check_target(url: str, *, allow_private: bool) -> str | None:
    """Why ``url`` cannot be a webhook target, or None when it can: http(s) with a host, and (unless
    ``allow_private``) one whose every address is public."""
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as exc:  # a port out of range or not a number, a broken IPv6 literal
        return f"is not a valid URL ({exc})"
    if parts.scheme not in ("http", "https") or not parts.hostname:
        return "must be an http:// or https:// URL with a host"
    if allow_private:
        return None
    host = parts.hostname
    try:
        addresses = {info[4][0] for info in socket.getaddrinfo(host, port or 443, type=socket.SOCK_STREAM)}
    except (OSError, UnicodeError):
        return f"the host {host!r} cannot be resolved"
    blocked = sorted(a for a in addresses if private_address(str(a)))
    if blocked:
        return (
            f"the host {host!r} is a private, loopback or link-local address ({blocked[0]}); such targets are "
            "refused unless the operator sets METAIRL_WEBHOOK_ALLOW_PRIVATE=true"
        )
    return None


def notify_job_end(session: Session, job_id: str, status: JobStatus) -> None:
    """Add a pending delivery of ``job.<status>`` to each of the job's lab's webhooks that wants it
    (flushed with the caller's transaction, never committed here)."""
    from service.api.schemas.jobs import JobOut  # the job as the API shows it: the body's ``data``

    kind = event_type(status)
    lab_id = session.execute(select(Job.lab_id).where(Job.id == job_id)).scalar_one()
    hooks = [
        h
        for h in session.execute(select(Webhook).where(Webhook.lab_id == lab_id)).scalars()
        if kind in h.events
    ]
    if not hooks:
        return
    job = session.execute(
        select(Job).where(Job.id == job_id).execution_options(populate_existing=True)
    ).scalar_one()
    payload = {"type": kind, "data": JobOut.of(job).model_dump(mode="json")}
    for hook in hooks:
        session.add(
            WebhookDelivery(id=new_id("msg"), webhook_id=hook.id, job_id=job_id, type=kind, payload=payload)
        )
