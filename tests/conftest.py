"""Shared test fixtures: where the real data is, and a skip when it is absent."""

from __future__ import annotations

from pathlib import Path

import pytest
from world import world  # noqa: F401  (the synthetic test world, a session fixture)

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
DATA = SHARED / "data"
REFERENCE = DATA / "reference"
HDM05 = DATA / "hdm05_cut"

NO_DATA_REASON = (f"real mocap data not present: {DATA} is missing (it lives in ../shared/ beside "
                  "the repository on development machines and CI)")


def require_data() -> Path:
    """Skip the calling test unless ../shared/data exists; return its path."""
    if not DATA.is_dir():
        pytest.skip(NO_DATA_REASON)
    return DATA


@pytest.fixture
def data_dir() -> Path:
    return require_data()


@pytest.fixture
def browser(tmp_path):
    """A headless Chromium (``tests/browser.py``) with its own profile and downloads
    folder, closed after the test; mark the test ``browser.needs_chromium``."""
    from browser import Browser, chromium

    b = Browser(chromium(), tmp_path / "profile", downloads=tmp_path / "downloads")
    yield b
    b.close()
