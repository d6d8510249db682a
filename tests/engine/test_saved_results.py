"""`FitResult.save` / `load`: a saved fit comes back whole, and any other file is `InvalidInput` at ``/file``
(never numpy's hint to unpickle it, nor a raw zip, zlib or JSON error)."""

from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from metairl_engine import FitConfig, InvalidInput
from metairl_engine.fit import fit
from metairl_engine.results import SAVE_FORMAT, FitResult
from tests.engine.helpers import goal_tasks_with_features

SAVED = FitConfig(hidden=(8,), max_steps=5, ensemble=4)
"""The saved fit's config: 4 members, as many as the automatic ensemble fits 2 tasks of 25 states with."""


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small fit's file."""
    features = np.random.default_rng(0).normal(size=(25, 3)).astype(np.float32)
    path = tmp_path_factory.mktemp("fit") / "fit.npz"
    fit(goal_tasks_with_features(features), SAVED).save(path)
    return path


def rewritten(saved: Path, tmp_path: Path, change: dict[str, object]) -> Path:
    """The saved file with some members replaced (a member set to None is left out)."""
    with np.load(saved) as stored:
        members = {name: stored[name] for name in stored.files}
    members |= {k: v for k, v in change.items() if v is not None}
    members = {k: v for k, v in members.items() if change.get(k, 0) is not None}
    path = tmp_path / "changed.npz"
    np.savez(path, **members)
    return path


def test_a_saved_fit_loads_as_it_was(saved: Path) -> None:
    loaded = FitResult.load(saved)
    assert loaded.config == SAVED and loaded.rewards.shape == (2, 25)


def test_a_result_prints_as_one_line_of_shapes_and_compares_by_identity(saved: Path) -> None:
    """A notebook shows the result without every array in full; == between two never asks an array for a truth
    value (compare the arrays with np.array_equal)."""
    loaded, again = FitResult.load(saved), FitResult.load(saved)
    text = repr(loaded)
    assert (
        text.startswith("FitResult(2 tasks × 25 states × 5 actions") and "\n" not in text and len(text) < 200
    )
    assert loaded == loaded and loaded != again and np.array_equal(loaded.rewards, again.rewards)


def test_loading_where_no_file_is_says_so(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no file at"):
        FitResult.load(tmp_path / "nothing.npz")
    with pytest.raises(FileNotFoundError):
        FitResult.load(tmp_path)  # a folder


@pytest.mark.parametrize(
    "damage",
    [
        lambda data: data[: len(data) // 2],  # truncated
        lambda data: data[:200] + bytes(b ^ 0xFF for b in data[200:400]) + data[400:],  # bytes flipped
        lambda data: b"",  # empty
        lambda data: b"time,x,y\n0,1,2\n",  # a text file
    ],
)
def test_a_damaged_or_foreign_file_is_invalid_input_at_file(
    saved: Path, tmp_path: Path, damage: object
) -> None:
    path = tmp_path / "damaged.npz"
    path.write_bytes(damage(saved.read_bytes()))  # type: ignore[operator]
    with pytest.raises(InvalidInput) as exc:
        FitResult.load(path)
    assert [i.pointer for i in exc.value.issues] == ["/file"]
    assert "is not a result written by FitResult.save" in str(exc.value) and "pickle" not in str(exc.value)


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ({"meta": None}, "not a result"),
        ({"rewards": None}, "not a result"),
        ({"meta": np.array("{not json")}, "not a result"),
        ({"meta": np.array(json.dumps([1, 2]))}, "not a result"),
        ({"rewards": np.zeros((7, 3))}, "do not fit together"),
        ({"meta": np.array(json.dumps({"format": 2}))}, "saved in format 2; this metairl reads 1"),
    ],
)
def test_a_file_missing_a_part_or_with_arrays_that_do_not_fit_is_invalid_input(
    saved: Path, tmp_path: Path, change: dict[str, object], words: str
) -> None:
    with pytest.raises(InvalidInput) as exc:
        FitResult.load(rewritten(saved, tmp_path, change))
    assert [i.pointer for i in exc.value.issues] == ["/file"] and words in str(exc.value)
    assert zipfile.is_zipfile(io.BytesIO(saved.read_bytes()))  # the original is untouched


def with_meta(saved: Path, tmp_path: Path, edit: Callable[[dict[str, Any]], None]) -> Path:
    """The saved file with its meta edited in place by ``edit``."""
    with np.load(saved) as stored:
        meta = json.loads(str(stored["meta"]))
    edit(meta)
    return rewritten(saved, tmp_path, {"meta": np.array(json.dumps(meta))})


@pytest.mark.parametrize(
    ("edit", "words"),
    [
        (lambda meta: meta["config"].pop("tabular_choice"), "lacks the setting 'tabular_choice'"),
        (lambda meta: meta["config"].update(momentum=0.9), "has the setting 'momentum', unknown"),
        (lambda meta: meta["config"].update(max_steps=-1), "config whose /config/max_steps"),
    ],
    ids=["lacking", "unknown", "refused value"],
)
def test_a_config_lacking_a_setting_or_with_an_unknown_or_refused_one_is_invalid_input_at_file(
    saved: Path, tmp_path: Path, edit: Callable[[dict[str, Any]], None], words: str
) -> None:
    with pytest.raises(InvalidInput) as exc:
        FitResult.load(with_meta(saved, tmp_path, edit))
    assert [i.pointer for i in exc.value.issues] == ["/file"] and words in str(exc.value)


def test_a_config_is_refused_naming_every_setting_it_lacks(saved: Path, tmp_path: Path) -> None:
    def drop_two(meta: dict[str, Any]) -> None:
        del meta["config"]["stay_at_ends"], meta["config"]["shrink_deviations"]

    with pytest.raises(InvalidInput) as exc:
        FitResult.load(with_meta(saved, tmp_path, drop_two))
    assert [i.message for i in exc.value.issues] == [
        "was saved with a config that lacks the setting 'shrink_deviations'",
        "was saved with a config that lacks the setting 'stay_at_ends'",
    ]


def test_a_file_without_a_format_is_read_as_this_format_and_refused_if_its_config_lacks_a_setting(
    saved: Path, tmp_path: Path
) -> None:
    with np.load(saved) as stored:
        assert json.loads(str(stored["meta"]))["format"] == SAVE_FORMAT
    whole = FitResult.load(with_meta(saved, tmp_path, lambda meta: meta.pop("format")))
    assert whole.config == SAVED

    def older(meta: dict[str, Any]) -> None:
        del meta["format"], meta["config"]["tabular_choice"]

    with pytest.raises(InvalidInput) as exc:
        FitResult.load(with_meta(saved, tmp_path, older))
    assert [i.pointer for i in exc.value.issues] == ["/file"] and "'tabular_choice'" in str(exc.value)
