"""A lab's webhooks and their deliveries (sending them is `worker.webhooks`)."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from service.store.deletion import forget_requests
from service.store.ids import new_id
from service.store.models.webhooks import Webhook, WebhookDelivery
from service.store.owned import get_owned
from service.store.paging import PageParams, RowPage, paginate

RECENT_DELIVERIES = 20
"""Deliveries shown with a webhook, newest first."""


def create_webhook(session: Session, *, lab_id: str, url: str, events: list[str], secret: str) -> Webhook:
    """Add a webhook (flushed, not committed)."""
    row = Webhook(id=new_id("whk"), lab_id=lab_id, url=url, events=events, secret=secret)
    session.add(row)
    session.flush()
    return row


def get_webhook(session: Session, webhook_id: str, *, lab_id: str) -> Webhook:
    """The lab's webhook, or 404."""
    return get_owned(session, Webhook, webhook_id, lab_id=lab_id, what="webhook")


def count_webhooks(session: Session, *, lab_id: str) -> int:
    """How many webhooks the lab has."""
    return session.execute(select(func.count()).where(Webhook.lab_id == lab_id)).scalar_one()


def list_webhooks(session: Session, *, lab_id: str, page: PageParams) -> RowPage[Webhook]:
    """One page of the lab's webhooks, newest first."""
    query = select(Webhook).where(Webhook.lab_id == lab_id)
    return paginate(session, query, page, key=(Webhook.created_at, Webhook.id))


def delete_webhook(session: Session, webhook: Webhook) -> None:
    """Delete the webhook and its deliveries (pending ones are never sent) and forget the POST that made it."""
    forget_requests(session, [webhook.id])
    session.delete(webhook)
    session.flush()


def recent_deliveries(
    session: Session, webhook: Webhook, *, limit: int = RECENT_DELIVERIES
) -> list[WebhookDelivery]:
    """The webhook's latest deliveries, newest first."""
    query = (
        select(WebhookDelivery)
        .where(WebhookDelivery.webhook_id == webhook.id)
        .order_by(WebhookDelivery.created_at.desc(), WebhookDelivery.id.desc())
        .limit(limit)
    )
    return list(session.execute(query).scalars())
