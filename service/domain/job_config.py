"""A job's ``config`` at the HTTP edge: a pydantic model generated field by field from the engine's `FitConfig`.

Each setting's type, default, range (the field's `bounds` metadata) and description (its docstring in
`metairl_engine/config.py`) come from `FitConfig`, so the OpenAPI schema documents every setting and cannot
drift from the engine. Types and ranges are checked here (`valid_settings`), as issues naming
``/config/<field>`` that join the submission's other checks (`service.jobs.submit`: the size limits, what
needs the demonstrator's MDPs, ``baseline_features``) in one 422.
"""

from __future__ import annotations

import ast
import inspect
import textwrap
from dataclasses import fields
from functools import cache
from typing import Annotated, Any, get_args, get_origin, get_type_hints

from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictInt, ValidationError, create_model

from metairl_engine.config import FitConfig
from metairl_engine.errors import Issue
from service.domain.common import AsSent, Number
from service.problems import body_issues


@cache
def attribute_docstrings(cls: type) -> dict[str, str]:
    """The docstring under each annotated attribute of ``cls``'s body (PEP 257's attribute docstrings)."""
    body = ast.parse(textwrap.dedent(inspect.getsource(cls))).body[0]
    assert isinstance(body, ast.ClassDef)
    docs = {}
    for node, after in zip(body.body, body.body[1:], strict=False):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(after, ast.Expr)
            and isinstance(after.value, ast.Constant)
            and isinstance(after.value.value, str)
        ):
            docs[node.target.id] = inspect.cleandoc(after.value.value)
    return docs


def http_type(hint: Any) -> Any:
    """The pydantic type of a `FitConfig` annotation: booleans, integers and numbers strict (``"yes"`` is no
    boolean, ``true`` no number, ``"10"`` or 10.5 no integer), floats finite, tuples as JSON arrays of strict
    integers."""
    if hint is bool:
        return StrictBool
    if hint is int:
        return StrictInt
    if hint is float:
        return Annotated[Number, Field(allow_inf_nan=False)]
    if get_origin(hint) is tuple:
        return tuple[StrictInt, ...]
    args = get_args(hint)
    if type(None) in args and len(args) == 2:
        return http_type(next(a for a in args if a is not type(None))) | None
    return hint


def config_model() -> type[BaseModel]:
    """The `JobConfig` model: one optional field per `FitConfig` field, unknown settings refused."""
    hints = get_type_hints(FitConfig)
    docs = attribute_docstrings(FitConfig)
    definitions: dict[str, Any] = {}
    for f in fields(FitConfig):
        definitions[f.name] = (
            http_type(hints[f.name]),
            Field(default=f.default, description=docs.get(f.name), **dict(f.metadata)),
        )
    return create_model(
        "JobConfig",
        __config__=ConfigDict(extra="forbid", json_schema_extra={"description": FitConfig.__doc__}),
        **definitions,
    )


JobConfig = config_model()
"""A job's fit settings (`FitConfig`'s contract names); omitted settings take their defaults."""


ConfigAsSent = Annotated[Any, AsSent(JobConfig | None)]
"""A submission's ``config`` as it came, documented as `JobConfig`: `valid_settings` checks it beside the
submission's other checks (`service.jobs.submit`)."""


def valid_settings(sent: Any) -> tuple[BaseModel, list[Issue]]:
    """A submission's ``config`` as sent (None: every default) as a `JobConfig` of the settings that pass their
    type and range checks, the others left at their defaults, with an issue at ``/config/...`` per problem:
    the checks of the valid settings still run, so a bad type and a hidden layer over the limit come in one
    answer."""
    try:
        return JobConfig.model_validate({} if sent is None else sent), []
    except ValidationError as exc:
        issues = [Issue(f"/config{i.pointer}", i.message) for i in body_issues(exc, sent)]
        failed = {e["loc"][0] for e in exc.errors() if e["loc"]}
        kept = {k: v for k, v in sent.items() if k not in failed} if isinstance(sent, dict) else {}
        return JobConfig.model_validate(kept), issues


def fit_config(config: BaseModel) -> FitConfig:
    """The engine's `FitConfig` of a validated `JobConfig`; `InvalidInput` if it fails the engine's own checks."""
    return FitConfig.from_dict(config.model_dump())


NETWORKS = ("meta_irl",)
"""The methods that fit networks: the only ones that read the networks' settings."""

NETWORK_SETTINGS = (
    "sharing",
    "sharing_weight",
    "sharing_states",
    "sharing_blocks",
    "baseline_features",
    "baseline_elsewhere_weight",
    "task_coordinates",
    "task_features",
    "shrink_deviations",
    "tabular_inputs",
    "tabular_choice",
    "backup",
    "bgi_k",
    "hidden",
    "fourier_octaves",
    "learning_rate",
    "holdout_fraction",
    "patience",
    "ensemble",
    "seed",
)
"""Settings only the networks' fit reads: the tabular solvers (`maxent.fit_maxent`) read only method,
confidence, max_steps and tolerance, and shared_maxent stay_at_ends too."""

SETTINGS_ONLY_WITH: tuple[tuple[str, str, tuple[Any, ...] | None, str], ...] = (
    *((name, "method", NETWORKS, 'method "meta_irl"') for name in NETWORK_SETTINGS),
    ("stay_at_ends", "method", ("meta_irl", "shared_maxent"), 'method "meta_irl" or "shared_maxent"'),
    ("bgi_k", "backup", ("bgi",), 'backup "bgi"'),
    ("sharing_weight", "sharing", None, "sharing"),
    ("sharing_states", "sharing", None, "sharing"),
)
"""(setting, the setting it depends on, the values of that setting that use it — None: any but "none" — and
how to say so): a setting the fit reads only under another's values. A setting may have several rows; the
first that applies is the one said, and lines come in `FitConfig`'s order of settings."""


def ignored_settings(config: dict[str, Any]) -> list[str]:
    """One line per setting of a job's ``config`` changed from its default where another setting makes the fit
    ignore it (`SETTINGS_ONLY_WITH`): accepted, as any valid config is, but said, so a lab does not read a
    result as shaped by it."""
    defaults = FitConfig().to_dict()  # as a job stores them: lists, not tuples
    lines: dict[str, str] = {}
    for name, other, used_with, what in SETTINGS_ONLY_WITH:
        value = config.get(other, defaults[other])
        used = value != "none" if used_with is None else value in used_with
        if name in config and config[name] != defaults[name] and not used and name not in lines:
            lines[name] = f"{name} is used only with {what}; this job has {other} {value!r}"
    return [lines[name] for name in defaults if name in lines]  # in the config's own order
