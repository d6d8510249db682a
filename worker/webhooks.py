"""Sending webhook deliveries (docs/api.md, "Webhooks"): a thread of every worker's main process.

Every ``webhook_poll_s`` it takes the pending deliveries that are due, claims each with a conditional
UPDATE (so two workers never send one delivery at once), POSTs it signed per the Standard Webhooks spec
and records the outcome: ``delivered`` on a 2xx answer; otherwise the error and the next attempt, after an
exponential backoff, until ``webhook_max_attempts`` attempts made it ``failed``. It runs beside the pool
processes, so a slow or dead receiver never holds up a fit.
"""

from __future__ import annotations

import json
import logging
import threading
from datetime import datetime, timedelta

import httpx
from sqlalchemy import select, update
from sqlalchemy.orm import Session, sessionmaker

from service.jobs.webhooks import backoff, check_target, sign
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.webhooks import Webhook, WebhookDelivery

log = logging.getLogger(__name__)

BATCH = 20
"""Most deliveries sent in one pass."""
LEASE = timedelta(seconds=60)
"""How long a claimed delivery is kept from other workers while this one sends it."""


def deliver_due(
    make_session: sessionmaker[Session], settings: Settings, *, now: datetime | None = None
) -> int:
    """Send every pending delivery whose time has come (at most `BATCH`); how many were attempted."""
    now = now or utcnow()
    with make_session() as session:
        due = session.execute(
            select(WebhookDelivery.id, WebhookDelivery.next_attempt_at)
            .where(WebhookDelivery.status == "pending", WebhookDelivery.next_attempt_at <= now)
            .order_by(WebhookDelivery.next_attempt_at)
            .limit(BATCH)
        ).all()
    sent = 0
    for delivery_id, due_at in due:
        with make_session() as session:
            claimed = session.execute(
                update(WebhookDelivery)
                .where(
                    WebhookDelivery.id == delivery_id,
                    WebhookDelivery.status == "pending",
                    WebhookDelivery.next_attempt_at == due_at,
                )
                .values(next_attempt_at=now + LEASE)
                .execution_options(synchronize_session=False)
            ).rowcount  # type: ignore[attr-defined]
            session.commit()
            if not claimed:
                continue  # another worker has it
            delivery = session.get_one(WebhookDelivery, delivery_id)
            hook = session.get_one(Webhook, delivery.webhook_id)
            code, error = send(hook, delivery, settings)
            delivery.attempts += 1
            delivery.last_attempt_at = utcnow()
            delivery.last_status_code = code
            delivery.last_error = error
            if error is None:
                delivery.status, delivery.delivered_at, delivery.next_attempt_at = "delivered", utcnow(), None
            elif delivery.attempts >= settings.webhook_max_attempts:
                delivery.status, delivery.next_attempt_at = "failed", None
            else:
                delivery.next_attempt_at = utcnow() + backoff(delivery.attempts, settings.webhook_backoff_s)
            session.commit()
            sent += 1
            log.info(
                "webhook %s, delivery %s attempt %d: %s",
                hook.id,
                delivery.id,
                delivery.attempts,
                error or "ok",
            )
    return sent


def send(hook: Webhook, delivery: WebhookDelivery, settings: Settings) -> tuple[int | None, str | None]:
    """POST one delivery; (the receiver's status code or None, why it failed or None)."""
    problem = check_target(hook.url, allow_private=settings.webhook_allow_private)
    if problem is not None:  # checked again at each attempt: a name may now resolve elsewhere
        return None, f"the URL cannot be used: {problem}"
    body = json.dumps(delivery.payload, separators=(",", ":")).encode()
    timestamp = int(utcnow().timestamp())
    headers = {
        "content-type": "application/json",
        "user-agent": "metairl-webhooks/1",
        "webhook-id": delivery.id,
        "webhook-timestamp": str(timestamp),
        "webhook-signature": sign(hook.secret, msg_id=delivery.id, timestamp=timestamp, body=body),
    }
    try:
        response = httpx.post(
            hook.url,
            content=body,
            headers=headers,
            timeout=settings.webhook_timeout_s,
            follow_redirects=False,
        )
    except httpx.HTTPError as exc:
        return None, f"{type(exc).__name__}: {exc}"[:500]
    if response.is_success:
        return response.status_code, None
    return response.status_code, f"the receiver answered HTTP {response.status_code}"


class Deliverer(threading.Thread):
    """The sending loop of a worker process (a daemon thread; `stop` ends it between passes)."""

    def __init__(self, make_session: sessionmaker[Session], settings: Settings):
        super().__init__(name="webhooks", daemon=True)
        self.make_session, self.settings = make_session, settings
        self.stopped = threading.Event()

    def run(self) -> None:
        while not self.stopped.wait(self.settings.webhook_poll_s):
            try:
                deliver_due(self.make_session, self.settings)
            except Exception:
                log.exception("webhook delivery pass failed; retrying in %s s", self.settings.webhook_poll_s)

    def stop(self) -> None:
        """End the loop after the current pass."""
        self.stopped.set()
