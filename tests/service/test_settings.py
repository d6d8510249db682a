"""Settings from the environment: a ``METAIRL_`` variable that names no setting is said out loud, with the
setting it most resembles, since pydantic-settings would ignore it and the setting keep its default."""

from __future__ import annotations

import logging

import pytest

from service.settings import get_settings, unknown_variables


def test_a_misspelt_setting_is_named_with_the_one_it_resembles_and_lab_tool_variables_are_not() -> None:
    environ = {"METAIRL_WORKER_CONCURENCY": "2", "METAIRL_API_KEY": "mirl_x", "METAIRL_URL": "u", "HOME": "/"}
    assert unknown_variables(environ) == [
        "METAIRL_WORKER_CONCURENCY is not a metairl setting and is ignored; did you mean "
        "METAIRL_WORKER_CONCURRENCY?"
    ]
    assert unknown_variables({"METAIRL_DATA_DIR": "d"}) == []


def test_reading_the_settings_warns_of_each_unknown_variable(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setenv("METAIRL_MAX_STATE_ACTION", "10")
    get_settings.cache_clear()
    try:
        with caplog.at_level(logging.WARNING, logger="metairl.settings"):
            get_settings()
    finally:
        get_settings.cache_clear()
    assert "did you mean METAIRL_MAX_STATE_ACTIONS?" in caplog.text
