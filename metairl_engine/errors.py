"""The engine's exception hierarchy: every bad input is an `InvalidInput` listing JSON-pointer issues."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Issue:
    """One thing wrong with an input: where (an RFC 6901 JSON pointer) and what, in a sentence."""

    pointer: str
    message: str


class EngineError(Exception):
    """Base class of everything the engine raises on purpose."""


class InvalidInput(EngineError, ValueError):
    """An MDP, demonstration set or config that cannot be used; `issues` says where and why."""

    def __init__(self, issues: Sequence[Issue]):
        self.issues: tuple[Issue, ...] = tuple(issues)
        shown = "; ".join(f"{i.pointer or '/'}: {i.message}" for i in self.issues[:5])
        more = f" (and {len(self.issues) - 5} more)" if len(self.issues) > 5 else ""
        super().__init__(shown + more)

    def prefixed(self, prefix: str) -> InvalidInput:
        """The same issues with `prefix` put in front of every pointer (to nest inside a request body)."""
        return InvalidInput([Issue(prefix + i.pointer, i.message) for i in self.issues])


class Cancelled(EngineError):
    """A fit stopped because its `should_stop` callback said so."""


class Diverged(EngineError):
    """A fit whose loss stopped being a finite number: its settings made the optimisation blow up."""


def check(issues: list[Issue]) -> None:
    """Raise `InvalidInput` if any issue was collected."""
    if issues:
        raise InvalidInput(issues)


def integer_issues(settings: object, pointer: str, minimums: dict[str, int]) -> list[Issue]:
    """An issue per field of ``settings`` named in ``minimums`` that is not an integer ≥ its minimum."""
    return [
        Issue(f"{pointer}/{name}", f"must be an integer ≥ {low}, got {getattr(settings, name)!r}")
        for name, low in minimums.items()
        if not isinstance(getattr(settings, name), int) or getattr(settings, name) < low
    ]
