"""Rate limits on `/v1` as ASGI middleware: requests per API key, and failed authentications per client address.

Each limit is a token bucket (``rate`` tokens a second, at most ``burst``). A request bearing a key takes a
token from that key's bucket; a request answered 401 takes one from its address's bucket, and while that
bucket is empty every `/v1` request from the address is refused before its key is looked at, so a key
guesser learns nothing more. Only keys this process has already answered with a 2xx pass the address's
refusal, so a lab sharing an address (a NAT, a proxy) with a guesser keeps working. A refusal is a 429 problem with
``Retry-After`` (whole seconds until a token).

The buckets live in the API process: with N processes (``metairl serve`` runs one per core) a client
spread over them gets up to N times each limit. The client address is the connection's, or the one a
trusted proxy forwards (uvicorn's ``--proxy-headers``, for ``--forwarded-allow-ips``); behind an untrusted
proxy all clients share the proxy's address and its failed-authentication bucket.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.problems import TooManyRequests, problem_response
from service.settings import Settings

MAX_BUCKETS = 100_000
"""Most buckets one limiter keeps; beyond it full (idle) buckets are dropped, then the oldest."""


class TokenBuckets:
    """Token buckets by name: each holds at most ``burst`` tokens and gains ``rate`` a second (a new one is full).

    Used from the event loop only (never from threads), so it needs no lock.
    """

    def __init__(self, rate: float, burst: int, *, clock: Callable[[], float] = time.monotonic):
        self.rate = rate
        self.burst = max(1, burst)
        self._clock = clock
        self._buckets: dict[str, tuple[float, float]] = {}  # name → (tokens, when counted)

    def _tokens(self, name: str, now: float) -> float:
        """The tokens of ``name``'s bucket at ``now``."""
        tokens, then = self._buckets.get(name, (self.burst, now))
        return min(self.burst, tokens + (now - then) * self.rate)

    def wait(self, name: str) -> float:
        """Seconds until ``name``'s bucket holds a token (0: it holds one now); takes nothing."""
        missing = 1 - self._tokens(name, self._clock())
        return max(0.0, missing / self.rate)

    def take(self, name: str) -> float:
        """Take a token from ``name``'s bucket: 0 if taken, else the seconds until one is there (nothing taken)."""
        now = self._clock()
        tokens = self._tokens(name, now)
        if tokens < 1:
            return (1 - tokens) / self.rate
        if name not in self._buckets and len(self._buckets) >= MAX_BUCKETS:
            self._forget_some(now)
        self._buckets[name] = (tokens - 1, now)
        return 0.0

    def _forget_some(self, now: float) -> None:
        """Drop the buckets that are full again (as good as new), and the oldest ones if that is not enough."""
        self._buckets = {n: b for n, b in self._buckets.items() if self._tokens(n, now) < self.burst}
        while len(self._buckets) >= MAX_BUCKETS:
            del self._buckets[next(iter(self._buckets))]


def retry_after(seconds: float) -> str:
    """A ``Retry-After`` value: whole seconds, at least 1."""
    return str(max(1, math.ceil(seconds)))


class RateLimit:
    """Refuse `/v1` requests over ``rate_limit_per_key`` (per API key) or from an address over
    ``rate_limit_per_ip`` failed authentications; a rate of 0 turns that limit off."""

    accepted: dict[str, None]
    """SHA-256 of the ``Authorization`` values answered 2xx (only a valid key gets one on `/v1`), oldest first,
    at most `MAX_BUCKETS`."""

    def __init__(self, app: ASGIApp, *, settings: Settings):
        self.app = app
        self.per_key = (
            TokenBuckets(settings.rate_limit_per_key, settings.rate_limit_per_key_burst)
            if settings.rate_limit_per_key > 0
            else None
        )
        self.per_ip = (
            TokenBuckets(settings.rate_limit_per_ip, settings.rate_limit_per_ip_burst)
            if settings.rate_limit_per_ip > 0
            else None
        )
        self.accepted = {}

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Answer 429 if a bucket of the request is empty; otherwise run it, counting a 401 against its address."""
        if scope["type"] != "http" or not scope["path"].startswith("/v1/"):
            await self.app(scope, receive, send)
            return
        address = (scope.get("client") or ("unknown", 0))[0]
        key = dict(scope["headers"]).get(b"authorization")
        digest = None if key is None else hashlib.sha256(key).hexdigest()
        if (
            self.per_ip is not None
            and digest not in self.accepted
            and (wait := self.per_ip.wait(address)) > 0
        ):
            refusal = TooManyRequests(
                f"Too many requests with a missing or invalid API key from {address}; retry after "
                f"{retry_after(wait)} s.",
                headers={"Retry-After": retry_after(wait)},
            )
            await problem_response(refusal)(scope, receive, send)
            return
        if self.per_key is not None and digest is not None:
            wait = self.per_key.take(digest)
            if wait > 0:
                refusal = TooManyRequests(
                    f"More than {self.per_key.rate:g} requests a second (bursts of {self.per_key.burst}) with "
                    f"this API key; retry after {retry_after(wait)} s.",
                    headers={"Retry-After": retry_after(wait)},
                )
                await problem_response(refusal)(scope, receive, send)
                return
        if self.per_ip is None:
            await self.app(scope, receive, send)
            return
        per_ip = self.per_ip

        async def counting_send(message: Message) -> None:
            """Send the response on; a 401 takes a token from the address's bucket, a 2xx marks the key accepted."""
            if message["type"] == "http.response.start":
                if message["status"] == 401:
                    per_ip.take(address)
                    self.accepted.pop(digest or "", None)
                elif 200 <= message["status"] < 300 and digest is not None and digest not in self.accepted:
                    if len(self.accepted) >= MAX_BUCKETS:
                        del self.accepted[next(iter(self.accepted))]
                    self.accepted[digest] = None
            await send(message)

        await self.app(scope, receive, counting_send)
