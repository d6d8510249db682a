"""Sending webhook deliveries (docs/api.md, "Webhooks"): a thread of every worker's main process.

Every ``webhook_poll_s`` it takes the pending deliveries that are due, lets labs take turns within limits
per lab, per target and in all (`choose`), claims each with a conditional UPDATE (so two workers never send
one delivery at once), POSTs it from a pool thread, signed per the Standard Webhooks spec, to the address
resolved and checked for this very request, and records the outcome: ``delivered`` on a 2xx answer; otherwise the error and the next attempt, after an
exponential backoff, until ``webhook_max_attempts`` attempts made it ``failed``. It runs beside the pool
processes, so a slow or dead receiver never holds up a fit.
"""

from __future__ import annotations

import json
import logging
import threading
from collections import Counter, deque
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import datetime, timedelta
from urllib.parse import urlsplit

import httpx
from sqlalchemy import func, select, update
from sqlalchemy.orm import Session, sessionmaker

from service.jobs.webhooks import backoff, resolve_target, sign
from service.settings import Settings
from service.store.models.base import utcnow
from service.store.models.webhooks import Webhook, WebhookDelivery

log = logging.getLogger(__name__)

LOOKAHEAD = 4
"""Due deliveries read per lab and pass, as a multiple of ``webhook_lab_concurrency``."""
LEASE = timedelta(seconds=60)
"""How long a claimed delivery is kept from other workers while this one sends it."""


@dataclass(frozen=True)
class Due:
    """A pending delivery whose time has come: its lab, and its target (host and port of the hook's URL)."""

    id: str
    due_at: datetime
    lab_id: str
    target: str


def due_deliveries(make_session: sessionmaker[Session], settings: Settings, now: datetime) -> list[Due]:
    """The pending deliveries due by ``now``, oldest first, at most ``LOOKAHEAD × webhook_lab_concurrency``
    per lab (a lab with thousands due does not hide another lab's one)."""
    rank = (
        func.row_number()
        .over(partition_by=Webhook.lab_id, order_by=(WebhookDelivery.next_attempt_at, WebhookDelivery.id))
        .label("rank")
    )
    ranked = (
        select(WebhookDelivery.id, WebhookDelivery.next_attempt_at, Webhook.lab_id, Webhook.url, rank)
        .join(Webhook, Webhook.id == WebhookDelivery.webhook_id)
        .where(WebhookDelivery.status == "pending", WebhookDelivery.next_attempt_at <= now)
        .subquery()
    )
    query = (
        select(ranked.c.id, ranked.c.next_attempt_at, ranked.c.lab_id, ranked.c.url)
        .where(ranked.c.rank <= LOOKAHEAD * settings.webhook_lab_concurrency)
        .order_by(ranked.c.next_attempt_at, ranked.c.id)
    )
    with make_session() as session:
        rows = session.execute(query).all()
    return [Due(r.id, r.next_attempt_at, r.lab_id, target_of(r.url)) for r in rows]


def target_of(url: str) -> str:
    """The host and port a webhook URL points at (the URL itself if it has none)."""
    try:
        parts = urlsplit(url)
        return f"{(parts.hostname or url).lower()}:{parts.port or parts.scheme}"
    except ValueError:
        return url


def choose(due: Sequence[Due], busy: Sequence[Due], settings: Settings) -> list[Due]:
    """Which of ``due`` to start now, given the deliveries ``busy`` sending: labs take turns (oldest first),
    and no lab, no target and not the whole process goes past its limit (``webhook_lab_concurrency``,
    ``webhook_target_concurrency``, ``webhook_concurrency``)."""
    free = settings.webhook_concurrency - len(busy)
    per_lab = Counter(d.lab_id for d in busy)
    per_target = Counter(d.target for d in busy)
    sending = {d.id for d in busy}
    queues: dict[str, deque[Due]] = {}
    for d in due:
        if d.id not in sending:
            queues.setdefault(d.lab_id, deque()).append(d)
    chosen: list[Due] = []
    while free > 0 and queues:
        for lab in list(queues):
            queue = queues[lab]
            while queue and free > 0 and per_lab[lab] < settings.webhook_lab_concurrency:
                d = queue.popleft()
                if per_target[d.target] < settings.webhook_target_concurrency:
                    chosen.append(d)
                    per_lab[lab] += 1
                    per_target[d.target] += 1
                    free -= 1
                    break
            if not queue or per_lab[lab] >= settings.webhook_lab_concurrency:
                del queues[lab]
    return chosen


def attempt(make_session: sessionmaker[Session], settings: Settings, due: Due) -> bool:
    """Claim ``due`` (a conditional UPDATE: no other worker sends it meanwhile), send it and record how it
    went; False if another worker had it or it was deleted (with its job) in between. No database
    connection is held while the receiver answers."""
    now = utcnow()
    with make_session() as session:
        claimed = session.execute(
            update(WebhookDelivery)
            .where(
                WebhookDelivery.id == due.id,
                WebhookDelivery.status == "pending",
                WebhookDelivery.next_attempt_at == due.due_at,
            )
            .values(next_attempt_at=now + LEASE)
            .execution_options(synchronize_session=False)
        ).rowcount  # type: ignore[attr-defined]
        session.commit()
        delivery = session.get(WebhookDelivery, due.id) if claimed else None
        hook = session.get(Webhook, delivery.webhook_id) if delivery is not None else None
        if delivery is None or hook is None:
            return False
        session.expunge_all()
    code, error = send(hook, delivery, settings)
    with make_session() as session:
        row = session.get(WebhookDelivery, due.id)
        if row is None:  # its job was deleted while it was being sent
            return True
        row.attempts += 1
        row.last_attempt_at = utcnow()
        row.last_status_code = code
        row.last_error = error
        if error is None:
            row.status, row.delivered_at, row.next_attempt_at = "delivered", utcnow(), None
        elif row.attempts >= settings.webhook_max_attempts:
            row.status, row.next_attempt_at = "failed", None
        else:
            row.next_attempt_at = utcnow() + backoff(row.attempts, settings.webhook_backoff_s)
        session.commit()
        log.info("webhook %s, delivery %s attempt %d: %s", hook.id, row.id, row.attempts, error or "ok")
    return True


def send(hook: Webhook, delivery: WebhookDelivery, settings: Settings) -> tuple[int | None, str | None]:
    """POST one delivery to the address its host resolves to now, checked again and pinned for this request
    (a name that re-resolves elsewhere meanwhile cannot redirect it); (the receiver's status code or None,
    why it failed or None)."""
    target = resolve_target(hook.url, allow_private=settings.webhook_allow_private)
    if isinstance(target, str):
        return None, f"the URL cannot be used: {target}"
    body = json.dumps(delivery.payload, separators=(",", ":")).encode()
    timestamp = int(utcnow().timestamp())
    headers = {
        "host": urlsplit(hook.url).netloc.rpartition("@")[2],
        "content-type": "application/json",
        "user-agent": "metairl-webhooks/1",
        "webhook-id": delivery.id,
        "webhook-timestamp": str(timestamp),
        "webhook-signature": sign(hook.secret, msg_id=delivery.id, timestamp=timestamp, body=body),
    }
    try:
        with httpx.Client(timeout=settings.webhook_timeout_s, follow_redirects=False) as client:
            request = client.build_request(
                "POST",
                target.pinned_url(),
                content=body,
                headers=headers,
                extensions={"sni_hostname": target.host},
            )
            response = client.send(request)
    except httpx.HTTPError as exc:
        return None, f"{type(exc).__name__}: {exc}"[:500]
    if response.is_success:
        return response.status_code, None
    return response.status_code, f"the receiver answered HTTP {response.status_code}"


class Deliverer(threading.Thread):
    """The sending loop of a worker process (a daemon thread; `stop` ends it between passes): every
    ``webhook_poll_s`` it starts the due deliveries `choose` picks on a pool of ``webhook_concurrency``
    threads, so a slow receiver holds one slot of its lab, never the loop."""

    def __init__(self, make_session: sessionmaker[Session], settings: Settings):
        super().__init__(name="webhooks", daemon=True)
        self.make_session, self.settings = make_session, settings
        self.stopped = threading.Event()
        self.pool = ThreadPoolExecutor(settings.webhook_concurrency, thread_name_prefix="webhook-send")
        self.busy: dict[str, Due] = {}
        self.lock = threading.Lock()

    def run(self) -> None:
        while not self.stopped.wait(self.settings.webhook_poll_s):
            try:
                self.dispatch()
            except Exception:
                log.exception("webhook delivery pass failed; retrying in %s s", self.settings.webhook_poll_s)
        self.pool.shutdown(wait=False, cancel_futures=True)

    def dispatch(self) -> int:
        """Start the deliveries due now that the limits leave room for; how many were started."""
        with self.lock:
            busy = list(self.busy.values())
        if len(busy) >= self.settings.webhook_concurrency:
            return 0
        chosen = choose(due_deliveries(self.make_session, self.settings, utcnow()), busy, self.settings)
        for due in chosen:
            with self.lock:
                self.busy[due.id] = due
            self.pool.submit(self._attempt, due)
        return len(chosen)

    def _attempt(self, due: Due) -> None:
        """Send one delivery on a pool thread, then free its slot."""
        try:
            attempt(self.make_session, self.settings, due)
        except Exception:
            log.exception("webhook delivery %s failed", due.id)
        finally:
            with self.lock:
                self.busy.pop(due.id, None)

    def stop(self) -> None:
        """End the loop after the current pass."""
        self.stopped.set()
