"""The worker's start-up check: it consumes only once the database is at this code's newest migration.

A worker never migrates: the API does at start-up (so do `metairl serve` and `metairl keys create`). A worker
started first (another machine, a container that came up before the API) waits, saying so once, instead of
failing every query; one whose database was migrated by newer code exits rather than write to a schema it does
not know.
"""

from __future__ import annotations

import sys
import time

from sqlalchemy.exc import OperationalError

from service.settings import Settings
from service.store.db import database_name, database_state

POLL_S = 3.0
"""Seconds between two looks at a database that is not ready yet."""
WHY = {
    "empty": "it has no tables yet",
    "behind": "it is at an older migration",
}
"""Why a database is not ready, by `database_state`."""


def say_on_stderr(line: str) -> None:
    """One line of the worker's own on stderr (Celery's logging is not set up this early)."""
    print(f"metairl worker: {line}", file=sys.stderr, flush=True)


def wait_until_migrated(settings: Settings, *, poll_s: float = POLL_S) -> None:
    """Return once the configured database is at the newest migration, checking every `poll_s` and saying one
    line each time the reason to wait changes; `SystemExit` (1) for a database migrated by newer code, and
    (130) when interrupted while waiting. Never creates a missing SQLite file."""
    name = database_name(settings)
    said = ""
    try:
        while True:
            try:
                state: str = database_state(settings)
            except OperationalError as exc:
                state, line = (
                    "unreachable",
                    f"waiting for the database at {name} to be reachable ({type(exc).__name__})",
                )
            else:
                if state == "current":
                    return
                if state == "ahead":
                    say_on_stderr(
                        f"the database at {name} was migrated by a newer metairl than this worker's; "
                        "upgrade this worker's metairl to the API's version"
                    )
                    raise SystemExit(1)
                line = (
                    f"waiting for the database at {name} to be migrated ({WHY[state]}): start the API, which "
                    "migrates it at start-up (or run `metairl keys create --lab NAME`)"
                )
            if state != said:
                say_on_stderr(f"{line}; checking again every {poll_s:g} s")
                said = state
            time.sleep(poll_s)
    except KeyboardInterrupt:
        raise SystemExit(130) from None
