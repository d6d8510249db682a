"""A job's ``config`` object checked against `FitConfig`'s field types before the engine's own range checks.

`FitConfig` validates values but trusts types (``"max_steps": "ten"`` would raise a TypeError deep in
its checks); this module names every wrongly typed or unknown field as ``/config/<field>`` first.
"""

from __future__ import annotations

import math
from dataclasses import fields
from functools import cache
from typing import Any, Literal, get_args, get_origin, get_type_hints

from metairl_engine.config import FitConfig
from metairl_engine.errors import InvalidInput, Issue, check


def parse_config(raw: object) -> FitConfig:
    """The `FitConfig` of a request's ``config`` (None → defaults); `InvalidInput` naming each bad field."""
    if raw is None:
        return FitConfig()
    if not isinstance(raw, dict):
        check([Issue("/config", "must be a JSON object of settings")])
    assert isinstance(raw, dict)
    hints = _field_types()
    issues = [Issue(f"/config/{key}", "is not a known setting") for key in raw if key not in hints]
    for key, value in raw.items():
        problem = type_problem(value, hints[key]) if key in hints else None
        if problem:
            issues.append(Issue(f"/config/{key}", problem))
    check(issues)
    try:
        return FitConfig.from_dict(raw)
    except TypeError as exc:  # a type combination the checks above did not foresee
        raise InvalidInput([Issue("/config", str(exc))]) from exc


@cache
def _field_types() -> dict[str, Any]:
    """Each `FitConfig` field's resolved type annotation."""
    hints = get_type_hints(FitConfig)
    return {f.name: hints[f.name] for f in fields(FitConfig)}


def type_problem(value: object, hint: Any) -> str | None:
    """Why ``value`` does not fit annotation ``hint`` (Literal, int, float, bool, tuple[int, ...]), or None."""
    if get_origin(hint) is Literal:
        options = get_args(hint)
        return None if value in options else "must be one of " + ", ".join(f"{o!r}" for o in options)
    if hint is bool:
        return None if isinstance(value, bool) else "must be true or false"
    if hint is int:
        return None if _is_int(value) else "must be an integer"
    if hint is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        return None if ok else "must be a finite number"
    if get_origin(hint) is tuple:
        ok = isinstance(value, list | tuple) and all(_is_int(v) for v in value)
        return None if ok else "must be a list of integers"
    return None


def _is_int(value: object) -> bool:
    """An integer that is not a boolean."""
    return isinstance(value, int) and not isinstance(value, bool)
