"""Memory handed back after large requests: glibc keeps freed heap mapped, so a process that parsed one big
upload would stay at its peak; after a write request that left the resident size `TRIM_ABOVE` higher than
before, ``malloc_trim(0)`` returns the free pages to the system (Linux with glibc; elsewhere a no-op)."""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os

from starlette.concurrency import run_in_threadpool
from starlette.types import ASGIApp, Receive, Scope, Send

log = logging.getLogger(__name__)

TRIM_ABOVE = 32 * 2**20
"""Growth of the resident size over one request that triggers a trim (bytes)."""
PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def resident_bytes() -> int:
    """This process's resident set size (0 where ``/proc`` is not available)."""
    try:
        with open("/proc/self/statm", "rb") as statm:
            return int(statm.read().split()[1]) * PAGE
    except OSError:
        return 0


def _malloc_trim() -> None:
    """Return the C heap's free pages to the system, if the C library can."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name)
        libc.malloc_trim(0)
    except (OSError, AttributeError, TypeError):
        log.debug("malloc_trim is not available")


class ReturnMemory:
    """Trim the C heap after a POST/PUT that grew the process by more than `TRIM_ABOVE`."""

    def __init__(self, app: ASGIApp):
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Run the request; afterwards compare the resident size and trim if it grew."""
        if scope["type"] != "http" or scope["method"] not in ("POST", "PUT"):
            await self.app(scope, receive, send)
            return
        before = resident_bytes()
        try:
            await self.app(scope, receive, send)
        finally:
            if resident_bytes() - before > TRIM_ABOVE:
                await run_in_threadpool(_malloc_trim)
