"""Bodies of `/v1/webhooks` (docs/api.md, "Webhooks"): the subscription, the webhook with its recent
deliveries, and the one answer that shows the secret."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from service.domain.common import FIRST_BAD_ITEM, AsSent, Body, Resource
from service.store.models.webhooks import Webhook, WebhookDelivery

EventName = Literal["job.succeeded", "job.failed", "job.cancelled"]

EXAMPLE_DELIVERY: dict[str, Any] = {
    "id": "msg_2Lx9Qk7vB0nT4sYw8cHe1A",
    "created_at": "2026-01-05T10:06:02Z",
    "type": "job.succeeded",
    "job_id": "job_V3n8sK2qLx0bT7mY4cW9rA",
    "status": "pending",
    "attempts": 2,
    "last_attempt_at": "2026-01-05T10:06:08Z",
    "last_status_code": 503,
    "last_error": "the receiver answered HTTP 503",
    "next_attempt_at": "2026-01-05T10:06:18Z",
    "delivered_at": None,
}
EXAMPLE_WEBHOOK: dict[str, Any] = {
    "id": "whk_8Tq3nL0xV5mB2sKc9YwR4e",
    "created_at": "2026-01-05T10:00:00Z",
    "url": "https://lab.example.org/metairl-hook",
    "events": ["job.succeeded", "job.failed", "job.cancelled"],
    "deliveries": [EXAMPLE_DELIVERY],
}


class WebhookIn(Body):
    """Call ``url`` with a signed POST when one of the lab's jobs ends as one of ``events``."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {"url": "https://lab.example.org/metairl-hook", "events": ["job.succeeded", "job.failed"]}
            ]
        }
    )

    url: str = Field(
        max_length=2000,
        description="An http(s) URL; private, loopback and link-local hosts are refused unless the operator "
        "allows them (METAIRL_WEBHOOK_ALLOW_PRIVATE).",
    )
    events: Annotated[list[EventName], FIRST_BAD_ITEM] = Field(
        default=["job.succeeded", "job.failed", "job.cancelled"],
        min_length=1,
        description="Event types to receive (default: all three).",
    )


WebhookSubmission = Annotated[dict[str, Any], AsSent(WebhookIn, sent=dict[str, Any])]
"""The body of `POST /v1/webhooks`: any JSON object, documented as `WebhookIn`; the route checks it with the
URL's target, so a bad event and a private host come in one 422."""


class DeliveryOut(BaseModel):
    """One event sent (or being sent) to the webhook, and how the attempts went."""

    model_config = ConfigDict(from_attributes=True, json_schema_extra={"examples": [EXAMPLE_DELIVERY]})

    id: str = Field(description="The `webhook-id` header of every attempt (receivers drop duplicates by it).")
    created_at: datetime
    type: str
    job_id: str
    status: Literal["pending", "delivered", "failed"] = Field(
        description="`pending` (retried at `next_attempt_at`), `delivered`, or `failed` after the last attempt."
    )
    attempts: int
    last_attempt_at: datetime | None
    last_status_code: int | None = Field(description="The receiver's HTTP status at the last attempt.")
    last_error: str | None = Field(description="Why the last attempt failed (null once delivered).")
    next_attempt_at: datetime | None
    delivered_at: datetime | None

    @classmethod
    def of(cls, row: WebhookDelivery) -> DeliveryOut:
        """The API view of a delivery row."""
        return cls.model_validate(row)


class WebhookOut(Resource):
    """A webhook and its latest deliveries (newest first); the secret is never shown again."""

    model_config = ConfigDict(json_schema_extra={"examples": [EXAMPLE_WEBHOOK]})

    url: str
    events: list[str]
    deliveries: list[DeliveryOut] = Field(description="The latest 20 deliveries, newest first.")

    @classmethod
    def of(cls, row: Webhook, deliveries: list[WebhookDelivery] | None = None) -> WebhookOut:
        """The API view of a webhook row with the given deliveries."""
        return cls(
            id=row.id,
            created_at=row.created_at,
            url=row.url,
            events=list(row.events),
            deliveries=[DeliveryOut.of(d) for d in deliveries or []],
        )


class WebhookCreated(WebhookOut):
    """The new webhook with its signing secret — shown this once: keep it to verify deliveries."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {**EXAMPLE_WEBHOOK, "deliveries": [], "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"}
            ]
        }
    )

    secret: str = Field(
        description="`whsec_` + base64 key of the HMAC-SHA256 signatures (Standard Webhooks)."
    )

    @classmethod
    def created(cls, row: Webhook) -> WebhookCreated:
        """The creation answer: the webhook and its secret."""
        return cls(**WebhookOut.of(row).model_dump(), secret=row.secret)
