"""Shared test fixtures.

Tests that read the reference corpus (18 real slicer files) and the real-Klipper motion
times carry the ``corpus`` marker; the data lives in the repository (``tests/data``, see
``tests/data/refdata.py`` and the PROVENANCE files there), so every clone has it.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parent / "data"


def _refdata():
    name = "flowtwin_test_refdata"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, DATA / "refdata.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """``tests/data``: reference data carried by the repository."""
    return DATA


@pytest.fixture(scope="session")
def klipper_dir() -> Path:
    """Real-Klipper reference: configs, ``print_times.tsv``, ``markers.tsv`` (its README)."""
    return DATA / "klipper"


@pytest.fixture(scope="session")
def corpus_dir() -> Path:
    """The 18 real slicer G-code files, decompressed (plus PROVENANCE.tsv, ANCHORS.tsv)."""
    return _refdata().corpus_dir()
