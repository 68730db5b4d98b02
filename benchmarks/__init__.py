"""Benchmarks of flowtwin (``make bench``): figures and ratios against named peers.

The reference corpus and the real-Klipper configs come from the repository's test data
(``tests/data``, decompressed once into ``tests/data/.cache``): ``CORPUS`` and ``KLIPPER``.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KLIPPER = ROOT / "tests" / "data" / "klipper"


def corpus_dir() -> Path:
    """The 18 real slicer files as plain ``.gcode`` (see ``tests/data/refdata.py``)."""
    spec = importlib.util.spec_from_file_location("flowtwin_bench_refdata",
                                                  ROOT / "tests" / "data" / "refdata.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path: Path = module.corpus_dir()
    return path
