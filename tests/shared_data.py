"""The real recordings of ``../shared/data`` (beside the checkout, as CI has it): where, and skipping without them."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parent.parent.parent / "shared" / "data"


def shared_data(sub: str) -> Path:
    """``../shared/data/<sub>``; skips the test when absent locally, fails it in CI (``CI`` set)."""
    path = SHARED_DATA / sub
    if not path.exists():
        if os.environ.get("CI"):
            pytest.fail(f"{path} is missing: CI must have shared/data beside the checkout")
        pytest.skip(f"{path} is absent (real recordings live beside the checkout)")
    return path
