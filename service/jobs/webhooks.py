"""Webhooks on job end (docs/api.md, "Webhooks"): the events, the targets allowed, the Standard Webhooks
signature, and the delivery rows written with a job's final status.

`notify_job_end` is called by `service.jobs.transitions.transition` inside the transaction that records the
final status, so a delivery exists exactly when the ending was committed. The workers send deliveries
(`worker.webhooks`); nothing here makes a network call except `resolve_target`'s name lookup.
"""

from __future__ import annotations

import base64
import ipaddress
import secrets
import socket
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from urllib.parse import urlsplit, urlunsplit

from sqlalchemy import select
from sqlalchemy.orm import Session
from standardwebhooks import Webhook as StandardWebhook

from service.store.ids import new_id
from service.store.models.job_status import JobStatus
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
    """The ``webhook-signature`` value (``v1,`` + base64 HMAC-SHA256 of ``{id}.{timestamp}.{body}``), made by the
    Standard Webhooks reference library, the one receivers verify with."""
    return StandardWebhook(secret).sign(msg_id, datetime.fromtimestamp(timestamp, UTC), body.decode("utf-8"))


def backoff(attempts: int, first_s: float) -> timedelta:
    """The wait after the ``attempts``-th failed attempt: ``first_s`` doubled each time, at most an hour."""
    return min(timedelta(seconds=first_s * 2 ** max(0, attempts - 1)), MAX_BACKOFF)


REFUSED_IPV6 = tuple(
    ipaddress.IPv6Network(n)
    for n in (
        "::/96",  # IPv4-compatible (deprecated) and the unspecified and loopback addresses
        "64:ff9b:1::/48",  # local-use NAT64
        "100::/64",  # discard-only
        "2001::/23",  # IETF protocol assignments, Teredo (2001::/32) among them
        "2001:db8::/32",  # documentation
        "3fff::/20",  # documentation
        "5f00::/16",  # segment routing (SRv6) identifiers
        "fc00::/7",  # unique local
        "fe80::/10",  # link-local
        "fec0::/10",  # site-local (deprecated)
        "ff00::/8",  # multicast
    )
)
"""IPv6 special-use prefixes a webhook may never target (IANA special-purpose registry); the IPv4-mapped
(``::ffff:0:0/96``), NAT64 (``64:ff9b::/96``) and 6to4 (``2002::/16``) prefixes are judged by the IPv4
address they embed."""
NAT64 = ipaddress.IPv6Network("64:ff9b::/96")


def embedded_ipv4(ip: ipaddress.IPv6Address) -> ipaddress.IPv4Address | None:
    """The IPv4 address an IPv4-mapped, NAT64 (well-known prefix) or 6to4 address reaches, if any."""
    if ip.ipv4_mapped is not None:
        return ip.ipv4_mapped
    if ip in NAT64:
        return ipaddress.IPv4Address(int(ip) & 0xFFFFFFFF)
    return ip.sixtofour


def private_address(address: str) -> bool:
    """Whether an IP address is one a service must not call for strangers: private, loopback, link-local,
    multicast, any other special-use address, or one that embeds such an IPv4 address."""
    ip = ipaddress.ip_address(address.split("%", 1)[0])
    if isinstance(ip, ipaddress.IPv6Address):
        embedded = embedded_ipv4(ip)
        if embedded is not None:
            return private_address(str(embedded))
        if any(ip in network for network in REFUSED_IPV6):
            return True
    return not ip.is_global or ip.is_multicast


@dataclass(frozen=True)
class Target:
    """A webhook URL resolved once: the address to connect to (pinned for the request) and the host name
    the request names (``Host`` header and TLS server name)."""

    url: str
    host: str
    address: str

    def pinned_url(self) -> str:
        """The URL with its host replaced by the resolved address (the port, path and query kept)."""
        parts = urlsplit(self.url)
        literal = f"[{self.address}]" if ":" in self.address else self.address
        netloc = literal + (f":{parts.port}" if parts.port else "")
        return urlunsplit((parts.scheme, netloc, parts.path, parts.query, ""))


def _host_and_port(url: str) -> tuple[str, int] | str:
    """The host and port (the scheme's default if none) of an http(s) URL, or why it is not one."""
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as exc:  # a port out of range or not a number, a broken IPv6 literal
        return f"is not a valid URL ({exc})"
    if parts.scheme not in ("http", "https") or not parts.hostname:
        return "must be an http:// or https:// URL with a host"
    if parts.username is not None or parts.password is not None:  # it would be stored and listed in clear
        return "must not carry a user name or password (user:pass@host); verify deliveries by their signature"
    return parts.hostname, port or (443 if parts.scheme == "https" else 80)


def resolve_target(url: str, *, allow_private: bool) -> Target | str:
    """``url`` resolved to one address that may be called, or why it cannot be a webhook target: an
    http(s) URL with a host whose every address is public (unless ``allow_private``)."""
    parsed = _host_and_port(url)
    if isinstance(parsed, str):
        return parsed
    host, port = parsed
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError):
        return f"the host {host!r} cannot be resolved"
    addresses = sorted({str(info[4][0]) for info in infos})
    if not addresses:
        return f"the host {host!r} cannot be resolved"
    blocked = [a for a in addresses if private_address(a)]
    if blocked and not allow_private:
        return (
            f"the host {host!r} is a private, loopback, link-local or other special-use address ({blocked[0]}); "
            "such targets are refused unless the operator sets METAIRL_WEBHOOK_ALLOW_PRIVATE=true"
        )
    return Target(url=url, host=host, address=addresses[0])


def check_target(url: str, *, allow_private: bool) -> str | None:
    """Why ``url`` cannot be a webhook target, or None when it can (`resolve_target`; with ``allow_private``
    only its form is checked, the name is resolved when a delivery is sent)."""
    if allow_private:
        parsed = _host_and_port(url)
        return parsed if isinstance(parsed, str) else None
    resolved = resolve_target(url, allow_private=False)
    return resolved if isinstance(resolved, str) else None


def notify_job_end(session: Session, job_id: str, status: JobStatus) -> None:
    """Add a pending delivery of ``job.<status>`` to each of the job's lab's webhooks that wants it
    (flushed with the caller's transaction, never committed here)."""
    from service.domain.jobs import JobOut  # the job as the API shows it: the body's ``data``

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
