"""The reference data the tests and benchmarks carry with them.

``tests/data/corpus`` holds the 18 real slicer files (gzip, with ``PROVENANCE.tsv`` and
``ANCHORS.tsv``); ``tests/data/klipper`` the real-Klipper motion times measured on them and
the printer configs they ran with (its ``README.md`` says how). The G-code is decompressed
once into a cache folder beside it (``tests/data/.cache``, ignored by git); a file there is
written atomically, so concurrent test workers never see half a file.
"""

from __future__ import annotations

import gzip
import os
import shutil
import tempfile
from pathlib import Path

DATA = Path(__file__).resolve().parent
CORPUS_GZ = DATA / "corpus"
KLIPPER = DATA / "klipper"
SEEDS = DATA / "seeds"
CACHE = DATA / ".cache"


def _fresh(out: Path, src: Path) -> bool:
    return out.exists() and out.stat().st_mtime_ns >= src.stat().st_mtime_ns


def decompressed(src: Path, cache: Path) -> Path:
    """The decompressed copy of ``src`` (``NAME.gz``) in ``cache``, made if missing or stale."""
    out = cache / src.name.removesuffix(".gz")
    if _fresh(out, src):
        return out
    cache.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=cache, prefix=f".{out.name}.")
    try:
        with gzip.open(src, "rb") as fin, os.fdopen(fd, "wb") as fout:
            shutil.copyfileobj(fin, fout, 1 << 20)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out


def corpus_dir(cache: Path = CACHE / "corpus") -> Path:
    """A folder holding the corpus as plain ``.gcode`` files (and its two TSV tables)."""
    for src in sorted(CORPUS_GZ.glob("*.gcode.gz")):
        decompressed(src, cache)
    for table in ("PROVENANCE.tsv", "ANCHORS.tsv"):
        dst = cache / table
        if not _fresh(dst, CORPUS_GZ / table):
            shutil.copyfile(CORPUS_GZ / table, dst)
    return cache
