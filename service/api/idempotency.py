"""`Idempotency-Key` on POST as ASGI middleware: the same key and body (per lab, within the TTL) replays the
first response and creates nothing; the same key with a different body is a 422; a key still running is a 409.

The key is claimed (a row with no response yet) before the request runs, so two concurrent retries cannot
both create; 5xx responses release the claim so the request can be retried. A claim is a lease of
``idempotency_lease_s`` that its request renews while it runs: if the request's process died, or the
database dropped before its response was recorded, the lease lapses and the next retry with the same key
and body takes the claim over and runs the request again (whatever the first run had committed stays;
the alternative was a key answering 409 until its TTL ran out). Every write of a claim names its holder,
so a holder that lost its claim records and releases nothing.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import secrets
from datetime import timedelta
from typing import Any

from sqlalchemy import delete, or_, select, update
from sqlalchemy.exc import IntegrityError, OperationalError
from sqlalchemy.orm import Session, sessionmaker
from starlette.concurrency import run_in_threadpool
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.api.auth import lab_for_key
from service.json_input import parse_json
from service.problems import ApiError, Conflict, Unprocessable, database_unavailable, problem_response
from service.settings import Settings
from service.store.models.base import ID_LENGTH, utcnow
from service.store.models.idempotency import IdempotentRequest

log = logging.getLogger(__name__)

HEADER = b"idempotency-key"
MAX_KEY_LENGTH = 255
REPLAYED_HEADERS = {"content-type", "location"}


def fingerprint(scope: Scope, body: bytes) -> str:
    """SHA-256 of what makes two requests "the same": path, query, media type and body content.

    JSON is compared by value (key order and spacing do not matter); a multipart body with its random
    boundary removed.
    """
    headers = dict(scope["headers"])
    media, _, params = headers.get(b"content-type", b"").partition(b";")
    content = body
    if media.strip() == b"application/json":
        try:
            content = json.dumps(parse_json(body), sort_keys=True, separators=(",", ":")).encode()
        except ApiError:
            content = body
    elif b"boundary=" in params:
        boundary = params.split(b"boundary=", 1)[1].split(b";")[0].strip(b' "')
        content = body.replace(boundary, b"")
    digest = hashlib.sha256()
    for part in (scope["path"].encode(), scope.get("query_string", b""), media.strip(), content):
        digest.update(len(part).to_bytes(8, "big") + part)
    return digest.hexdigest()


def _bearer_key(scope: Scope) -> str | None:
    """The bearer token of the request, if any."""
    value = dict(scope["headers"]).get(b"authorization", b"").decode("latin-1")
    scheme, _, token = value.partition(" ")
    return token.strip() if scheme.lower() == "bearer" and token.strip() else None


class Idempotency:
    """Replays POST responses by (lab, Idempotency-Key); requests without the header pass straight through."""

    def __init__(self, app: ASGIApp, *, settings: Settings):
        self.app = app
        self.ttl = timedelta(seconds=settings.idempotency_ttl_s)
        self.lease = timedelta(seconds=settings.idempotency_lease_s)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Claim the key, run the request and store its response, or answer from the stored one."""
        if scope["type"] != "http" or scope["method"] != "POST":
            await self.app(scope, receive, send)
            return
        raw_key = dict(scope["headers"]).get(HEADER)
        bearer = _bearer_key(scope)
        if raw_key is None or bearer is None:
            await self.app(scope, receive, send)
            return
        key = raw_key.decode("latin-1").strip()
        makers: sessionmaker[Session] = scope["app"].state.sessionmaker
        if not key or len(key) > MAX_KEY_LENGTH:
            error = Unprocessable(
                f"The Idempotency-Key header must be 1 to {MAX_KEY_LENGTH} characters.",
                errors=[{"pointer": "", "parameter": "Idempotency-Key", "message": "has a bad length"}],
            )
            await problem_response(error)(scope, receive, send)
            return
        body = await read_body(receive)
        fp = fingerprint(scope, body)
        claim = secrets.token_hex(16)
        try:
            outcome = await run_in_threadpool(self._claim, makers, bearer, key, fp, claim)
        except OperationalError as exc:  # outside the app's exception handlers: answer its 503 here
            log.warning("database unavailable while claiming an Idempotency-Key: %s", exc.orig)
            outcome = database_unavailable()
        if isinstance(outcome, ApiError):
            await problem_response(outcome)(scope, receive, send)
            return
        if isinstance(outcome, IdempotentRequest):
            await _replay(outcome, send)
            return
        if outcome is None:  # no valid key: let the route answer 401
            await self.app(scope, replaying_receive(body, receive), send)
            return
        lab_id = outcome
        captured: dict[str, Any] = {"status": 500, "headers": [], "body": b"", "recorded": False}
        held: list[Message] = []

        async def recording_send(message: Message) -> None:
            """Hold the response until its last body part, record it, then send it: a retry arriving right
            after the answer always finds it recorded."""
            if message["type"] == "http.response.start":
                captured["status"] = message["status"]
                captured["headers"] = [
                    [k.decode("latin-1"), v.decode("latin-1")]
                    for k, v in message.get("headers", [])
                    if k.decode("latin-1").lower() in REPLAYED_HEADERS
                ]
                held.append(message)
                return
            if message["type"] != "http.response.body":
                await send(message)
                return
            captured["body"] += message.get("body", b"")
            held.append(message)
            if message.get("more_body", False):
                return
            await self._record(makers, lab_id, key, claim, captured)
            for part in held:
                await send(part)
            held.clear()

        renewing = asyncio.create_task(self._renew_while_running(makers, lab_id, key, claim))
        try:
            await self.app(scope, replaying_receive(body, receive), recording_send)
        finally:
            renewing.cancel()
            if not captured["recorded"]:  # no complete response: release the claim
                captured["status"] = 500
                await self._record(makers, lab_id, key, claim, captured)

    async def _record(
        self, makers: sessionmaker[Session], lab_id: str, key: str, claim: str, captured: dict[str, Any]
    ) -> None:
        """Store the captured response (or release the claim after a 5xx); a database outage leaves the lease
        to lapse so that a retry takes over."""
        captured["recorded"] = True
        try:
            await run_in_threadpool(self._finish, makers, lab_id, key, claim, captured)
        except OperationalError as exc:
            log.warning("database unavailable while recording Idempotency-Key %r: %s", key, exc.orig)

    def _claim(
        self, makers: sessionmaker[Session], bearer: str, key: str, fp: str, claim: str
    ) -> str | IdempotentRequest | ApiError | None:
        """Claim `key` for this request as `claim`: returns the lab id (go ahead), a finished row (replay), an
        error, or None when the API key is not valid. A running claim whose lease lapsed is taken over."""
        with makers() as session:
            lab = lab_for_key(session, bearer)
            if lab is None:
                return None
            lab_id = lab.id
            now = utcnow()
            session.execute(
                delete(IdempotentRequest).where(
                    IdempotentRequest.lab_id == lab_id, IdempotentRequest.created_at < now - self.ttl
                )
            )
            session.add(
                IdempotentRequest(
                    lab_id=lab_id, key=key, fingerprint=fp, claim=claim, leased_until=now + self.lease
                )
            )
            try:
                session.commit()
                return lab_id
            except IntegrityError:
                session.rollback()
            row = session.execute(
                select(IdempotentRequest).where(
                    IdempotentRequest.lab_id == lab_id, IdempotentRequest.key == key
                )
            ).scalar_one_or_none()
        if row is None:
            return Conflict("A request with this Idempotency-Key just finished failing; retry it.")
        if row.fingerprint != fp:
            return Unprocessable(
                "This Idempotency-Key was used with a different request body or path; use a new key.",
                errors=[
                    {
                        "pointer": "",
                        "parameter": "Idempotency-Key",
                        "message": "reused for a different request",
                    }
                ],
            )
        if row.status is None:
            if self._take_over(makers, row, claim):
                return lab_id
            return Conflict("A request with this Idempotency-Key is still being processed; retry shortly.")
        return row

    def _take_over(self, makers: sessionmaker[Session], row: IdempotentRequest, claim: str) -> bool:
        """Make `claim` the holder of the running `row` if its lease has lapsed (one of racing retries wins)."""
        now = utcnow()
        if row.leased_until is not None and row.leased_until >= now:
            return False
        with makers() as session:
            taken = session.execute(
                update(IdempotentRequest)
                .where(
                    IdempotentRequest.lab_id == row.lab_id,
                    IdempotentRequest.key == row.key,
                    IdempotentRequest.status.is_(None),
                    IdempotentRequest.claim.is_(None)
                    if row.claim is None
                    else IdempotentRequest.claim == row.claim,
                    or_(IdempotentRequest.leased_until.is_(None), IdempotentRequest.leased_until < now),
                )
                .values(claim=claim, leased_until=now + self.lease)
                .execution_options(synchronize_session=False)
            ).rowcount  # type: ignore[attr-defined]
            session.commit()
        if taken:
            log.warning(
                "Idempotency-Key %r of lab %s: lease lapsed; taken over by a retry", row.key, row.lab_id
            )
        return bool(taken)

    async def _renew_while_running(
        self, makers: sessionmaker[Session], lab_id: str, key: str, claim: str
    ) -> None:
        """Extend the claim's lease every third of it until cancelled (a failed renewal is retried next time)."""
        while True:
            await asyncio.sleep(self.lease.total_seconds() / 3)
            try:
                await run_in_threadpool(self.renew, makers, lab_id, key, claim)
            except Exception:
                log.exception("could not renew the lease of Idempotency-Key %r of lab %s", key, lab_id)

    def renew(self, makers: sessionmaker[Session], lab_id: str, key: str, claim: str) -> bool:
        """Extend the lease of `claim` on `key` by ``idempotency_lease_s`` from now; False if it is no longer held."""
        with makers() as session:
            renewed = session.execute(
                update(IdempotentRequest)
                .where(
                    IdempotentRequest.lab_id == lab_id,
                    IdempotentRequest.key == key,
                    IdempotentRequest.claim == claim,
                    IdempotentRequest.status.is_(None),
                )
                .values(leased_until=utcnow() + self.lease)
                .execution_options(synchronize_session=False)
            ).rowcount  # type: ignore[attr-defined]
            session.commit()
        return bool(renewed)

    @staticmethod
    def _finish(
        makers: sessionmaker[Session], lab_id: str, key: str, claim: str, captured: dict[str, Any]
    ) -> None:
        """Store the response for replay, or release the claim after a server error, if `claim` still holds it."""
        with makers() as session:
            row = session.get(IdempotentRequest, (lab_id, key))
            if row is None or row.claim != claim or row.status is not None:
                return
            if captured["status"] >= 500:
                session.delete(row)
            else:
                row.status = captured["status"]
                row.headers = captured["headers"]
                row.body = captured["body"]
                row.resource_id = _created_id(captured["status"], captured["body"])
                row.claim = None
                row.leased_until = None
            session.commit()


def _created_id(status: int, body: bytes) -> str | None:
    """The ``id`` of the resource a 2xx JSON response describes, if any (so deleting it forgets the request)."""
    if not 200 <= status < 300:
        return None
    try:
        document = json.loads(body)
    except ValueError:
        return None
    created = document.get("id") if isinstance(document, dict) else None
    return created if isinstance(created, str) and len(created) <= ID_LENGTH else None


async def read_body(receive: Receive) -> bytes:
    """The whole request body."""
    chunks = []
    while True:
        message = await receive()
        if message["type"] != "http.request":
            break
        chunks.append(message.get("body", b""))
        if not message.get("more_body", False):
            break
    return b"".join(chunks)


def replaying_receive(body: bytes, receive: Receive) -> Receive:
    """A `receive` that hands the already-read body to the app in one message, then defers to `receive`."""
    sent = False

    async def replaying() -> Message:
        """The stored body first, then whatever the server sends (e.g. a disconnect)."""
        nonlocal sent
        if sent:
            return await receive()
        sent = True
        return {"type": "http.request", "body": body, "more_body": False}

    return replaying


async def _replay(row: IdempotentRequest, send: Send) -> None:
    """Send the stored response again, marked with ``Idempotent-Replayed: true``."""
    headers = [(k.encode("latin-1"), v.encode("latin-1")) for k, v in row.headers or []]
    headers.append((b"idempotent-replayed", b"true"))
    body = row.body or b""
    headers.append((b"content-length", str(len(body)).encode()))
    await send({"type": "http.response.start", "status": row.status, "headers": headers})
    await send({"type": "http.response.body", "body": body})
