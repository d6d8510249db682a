"""`/v1/webhooks` (docs/api.md, "Webhooks"): a lab's URLs called when its jobs end, with their deliveries.

The workers send the deliveries (signed per the Standard Webhooks spec, retried with backoff); these routes
only manage subscriptions and show how the deliveries went.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response, status

from service.api.deps import LabDep, SessionDep, SettingsDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.pagination import Page, PageDep
from service.domain.webhooks import WebhookCreated, WebhookIn, WebhookOut
from service.jobs.webhooks import check_target, new_secret
from service.problems import Conflict, Unprocessable
from service.store import webhooks
from service.store.deletion import commit_deletion

router = APIRouter(tags=["webhooks"], responses=PROBLEM_RESPONSES)

NO_SUCH_WEBHOOK: dict[int | str, dict[str, Any]] = {404: {"description": "No such webhook in your lab."}}


@router.post(
    "/webhooks",
    status_code=status.HTTP_201_CREATED,
    summary="Subscribe a URL to job endings",
    responses={
        409: {"description": "The lab already has the most webhooks allowed (problem+json)."},
        422: {"description": "Not an http(s) URL, a private target, or an unknown event."},
    },
)
def create_webhook(
    body: WebhookIn, response: Response, session: SessionDep, lab: LabDep, settings: SettingsDep
) -> WebhookCreated:
    """Each time one of the lab's jobs ends as one of `events`, POST `{"type", "data": <the job>}` to `url`,
    signed with the returned `secret` (shown only now) per the Standard Webhooks spec."""
    if webhooks.count_webhooks(session, lab_id=lab.id) >= settings.webhook_max_per_lab:
        raise Conflict(
            f"Your lab already has {settings.webhook_max_per_lab} webhooks, the most allowed "
            "(METAIRL_WEBHOOK_MAX_PER_LAB); delete one first."
        )
    problem = check_target(body.url, allow_private=settings.webhook_allow_private)
    if problem is not None:
        raise Unprocessable(
            f"The webhook URL cannot be used: {problem}.", errors=[{"pointer": "/url", "message": problem}]
        )
    row = webhooks.create_webhook(
        session, lab_id=lab.id, url=body.url, events=sorted(set(body.events)), secret=new_secret()
    )
    session.commit()
    response.headers["Location"] = f"/v1/webhooks/{row.id}"
    return WebhookCreated.created(row)


@router.get("/webhooks", summary="List webhooks")
def list_webhooks(session: SessionDep, lab: LabDep, page: PageDep) -> Page[WebhookOut]:
    """The lab's webhooks, newest first (deliveries are shown on each webhook's own page)."""
    return Page[WebhookOut].of(webhooks.list_webhooks(session, lab_id=lab.id, page=page), WebhookOut.of)


@router.get("/webhooks/{webhook_id}", summary="Get a webhook and its deliveries", responses=NO_SUCH_WEBHOOK)
def read_webhook(webhook_id: str, session: SessionDep, lab: LabDep) -> WebhookOut:
    """The webhook with its latest deliveries: status, attempts, last error and the next attempt's time."""
    row = webhooks.get_webhook(session, webhook_id, lab_id=lab.id)
    return WebhookOut.of(row, webhooks.recent_deliveries(session, row))


@router.delete(
    "/webhooks/{webhook_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    summary="Delete a webhook",
    responses=NO_SUCH_WEBHOOK,
)
def delete_webhook(webhook_id: str, session: SessionDep, lab: LabDep) -> Response:
    """Stop calling the URL; deliveries not yet sent are dropped."""
    webhooks.delete_webhook(session, webhooks.get_webhook(session, webhook_id, lab_id=lab.id))
    commit_deletion(session)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
