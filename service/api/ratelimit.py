"""Rate limits on `/v1` as ASGI middleware: requests per API key, and failed authentications per client address.

Each limit is a sliding window counted by the `limits` library (`SlidingWindowCounterRateLimiter` on its
`MemoryStorage`): a setting's ``rate`` a second in bursts of ``burst`` becomes at most ``burst`` requests in a
window of ``burst / rate`` seconds (`window`). A request bearing a key counts against that key's window; a
request answered 401 counts against its address's window, and while that window is full every `/v1` request
from the address is refused before its key is looked at, so a key guesser learns nothing more. Only keys this
process has already answered with a 2xx pass the address's refusal, so a lab sharing an address (a NAT, a
proxy) with a guesser keeps working. A refusal is a 429 problem with ``Retry-After`` (whole seconds until the
window lets a request in, from the limiter's window statistics).

The windows live in the API process: with N processes (``metairl serve`` runs one per core) a client
spread over them gets up to N times each limit. The client address is the connection's, or the one a
trusted proxy forwards (uvicorn's ``--proxy-headers``, for ``--forwarded-allow-ips``); behind an untrusted
proxy all clients share the proxy's address and its failed-authentication window.
"""

from __future__ import annotations

import hashlib
import math
import time

from limits import RateLimitItem, RateLimitItemPerSecond
from limits.storage import MemoryStorage
from limits.strategies import SlidingWindowCounterRateLimiter
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.problems import TooManyRequests, problem_response
from service.settings import Settings

MAX_ACCEPTED = 100_000
"""Most accepted keys one process remembers (the oldest is forgotten first)."""


def window(rate: float, burst: int) -> RateLimitItem:
    """``rate`` requests a second in bursts of ``burst`` as a window: ``burst`` requests in ``burst / rate``
    seconds, rounded to whole seconds (the library's finest window); a burst below one second's requests is
    raised to them, so the sustained rate is never cut below ``rate``."""
    amount = max(1, burst, math.ceil(rate))
    return RateLimitItemPerSecond(amount, max(1, round(amount / rate)))


class Limit:
    """One limit: a sliding window per name (an API key's digest, or an address) in this process's memory."""

    def __init__(self, rate: float, burst: int):
        self.rate, self.burst = rate, burst
        self.item = window(rate, burst)
        self.limiter = SlidingWindowCounterRateLimiter(MemoryStorage())

    def wait(self, name: str) -> float | None:
        """None if ``name``'s window would let a request in now, else the seconds until it would; counts nothing."""
        return None if self.limiter.test(self.item, name) else self._reset_in(name)

    def take(self, name: str) -> float | None:
        """Count a request of ``name``: None if its window let it in, else the seconds until it would (uncounted)."""
        return None if self.limiter.hit(self.item, name) else self._reset_in(name)

    def _reset_in(self, name: str) -> float:
        """Seconds until ``name``'s window lets a request in, by the limiter's window statistics."""
        return max(0.0, self.limiter.get_window_stats(self.item, name).reset_time - time.time())


def retry_after(seconds: float) -> str:
    """A ``Retry-After`` value: whole seconds, at least 1."""
    return str(max(1, math.ceil(seconds)))


def too_many(why: str, wait: float) -> TooManyRequests:
    """The 429 refusal: ``why``, with the seconds to wait in its detail and its ``Retry-After``."""
    return TooManyRequests(
        f"{why}; retry after {retry_after(wait)} s.", headers={"Retry-After": retry_after(wait)}
    )


class RateLimit:
    """Refuse `/v1` requests over ``rate_limit_per_key`` (per API key) or from an address over
    ``rate_limit_per_ip`` failed authentications; a rate of 0 turns that limit off."""

    accepted: dict[str, None]
    """SHA-256 of the ``Authorization`` values answered 2xx (only a valid key gets one on `/v1`), oldest first,
    at most `MAX_ACCEPTED`."""

    def __init__(self, app: ASGIApp, *, settings: Settings):
        self.app = app
        self.per_key = (
            Limit(settings.rate_limit_per_key, settings.rate_limit_per_key_burst)
            if settings.rate_limit_per_key > 0
            else None
        )
        self.per_ip = (
            Limit(settings.rate_limit_per_ip, settings.rate_limit_per_ip_burst)
            if settings.rate_limit_per_ip > 0
            else None
        )
        self.accepted = {}

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Answer 429 if a window of the request is full; otherwise run it, counting a 401 against its address."""
        if scope["type"] != "http" or not scope["path"].startswith("/v1/"):
            await self.app(scope, receive, send)
            return
        address = (scope.get("client") or ("unknown", 0))[0]
        key = dict(scope["headers"]).get(b"authorization")
        digest = None if key is None else hashlib.sha256(key).hexdigest()
        if (
            self.per_ip is not None
            and digest not in self.accepted
            and (wait := self.per_ip.wait(address)) is not None
        ):
            why = f"Too many requests with a missing or invalid API key from {address}"
            await problem_response(too_many(why, wait))(scope, receive, send)
            return
        if (
            self.per_key is not None
            and digest is not None
            and (over := self.per_key.take(digest)) is not None
        ):
            why = f"More than {self.per_key.rate:g} requests a second (bursts of {self.per_key.burst}) with this API key"
            await problem_response(too_many(why, over))(scope, receive, send)
            return
        if self.per_ip is None:
            await self.app(scope, receive, send)
            return
        per_ip = self.per_ip

        async def counting_send(message: Message) -> None:
            """Send the response on; a 401 counts against the address's window, a 2xx marks the key accepted."""
            if message["type"] == "http.response.start":
                if message["status"] == 401:
                    per_ip.take(address)
                    self.accepted.pop(digest or "", None)
                elif 200 <= message["status"] < 300 and digest is not None and digest not in self.accepted:
                    if len(self.accepted) >= MAX_ACCEPTED:
                        del self.accepted[next(iter(self.accepted))]
                    self.accepted[digest] = None
            await send(message)

        await self.app(scope, receive, counting_send)
