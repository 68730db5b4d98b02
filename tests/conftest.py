"""Shared test fixtures.

Tests that read the reference corpus and Klipper oracle from ``../shared`` carry the
``shared`` marker; CI always has that folder beside the checkout.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("FLOWTWIN_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ``../shared`` folder (corpus, Klipper oracle, seeds); fails loudly if absent."""
    if not (SHARED / "corpus").is_dir():
        pytest.fail(f"reference data not found at {SHARED} (set FLOWTWIN_SHARED)")
    return SHARED


@pytest.fixture(scope="session")
def corpus_dir(shared_dir: Path) -> Path:
    """The 18 real slicer G-code files."""
    return shared_dir / "corpus"
