"""`/v1/webhooks` (docs/api.md, "Webhooks"): a lab's URLs called when its jobs end, with their deliveries.

The workers send the deliveries (signed per the Standard Webhooks spec, retried with backoff); these routes
only manage subscriptions and show how the deliveries went.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response, status

from metairl_engine.errors import Issue, check
from service.api.deps import LabDep, SessionDep, SettingsDep
from service.api.openapi import PROBLEM_RESPONSES
from service.api.pagination import Page, PageDep
from service.domain.webhooks import WebhookCreated, WebhookIn, WebhookOut, WebhookSubmission
from service.jobs.webhooks import check_target, new_secret
from service.problems import Conflict, gathering, validated
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
    body: WebhookSubmission, response: Response, session: SessionDep, lab: LabDep, settings: SettingsDep
) -> WebhookCreated:
    """Each time one of the lab's jobs ends as one of `events`, POST `{"type", "data": <the job>}` to `url`,
    signed with the returned `secret` (shown only now) per the Standard Webhooks spec."""
    issues: list[Issue] = []  # the body's problems and its URL target's, in one 422
    hook = gathering(issues, lambda: validated(WebhookIn, body))
    url = body.get("url")
    problem = (
        check_target(url, allow_private=settings.webhook_allow_private) if isinstance(url, str) else None
    )
    if problem is not None:
        issues.append(Issue("/url", problem))
    check(issues)
    assert hook is not None  # else check raised
    if webhooks.count_webhooks(session, lab_id=lab.id) >= settings.webhook_max_per_lab:
        raise Conflict(
            f"Your lab already has {settings.webhook_max_per_lab} webhooks, the most allowed "
            "(METAIRL_WEBHOOK_MAX_PER_LAB); delete one first."
        )
    row = webhooks.create_webhook(
        session, lab_id=lab.id, url=hook.url, events=sorted(set(hook.events)), secret=new_secret()
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
