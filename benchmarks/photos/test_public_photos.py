"""Real public photos of printed advance-factor patterns, read by ``from-image``
(``make photos``; not part of ``make test``).

The photos are public data fetched from other repositories and are **not committed**
(tests/data/kphoto/PROVENANCE.md, "Where the files are"): this suite reads them from the
folder named by ``FLOWTWIN_KPHOTO_DIR`` (``make photos KPHOTO_DIR=...``), checks each file's
SHA-256 against tests/data/kphoto/photos.json, and **fails** for a photo that is missing
(so a run without the photos cannot pass quietly). Each photo is read with its published
layout and compared with the K its author judged best (tolerance in steps of the pattern,
fixed before any photo was read). ``expect`` in the manifest says what the reader does:

* ``read`` — the best line lies within the tolerance of the nearest judged K;
* ``refuse`` — the reader refuses with the reason given (``refusal`` matches the message);
* ``miss`` — a documented miss (docs/calibration.md): read outside the tolerance; kept
  as a strict expected failure, so a reader that starts getting it right is noticed;
* ``pending`` — the judged K is recorded but the photo has not been read yet (a new check
  set between its declaration and its one reading): fails, there is no outcome to hold.

``FLOWTWIN_KPHOTO_DIR`` may name several folders joined by ``os.pathsep``
(``make photos KPHOTO_DIR="dir1 dir2"``).
"""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from typing import Any

import pytest


def _study() -> Any:
    # benchmarks/study_real_photos.py holds the manifest reader (also its command line)
    name = "flowtwin_study_real_photos"
    if name not in sys.modules:
        path = Path(__file__).resolve().parents[1] / "study_real_photos.py"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


STUDY = _study()
PHOTOS = list(STUDY.entries())


def _id(e: dict[str, Any]) -> str:
    return f"{e['split']}-{e['file']}"


@pytest.mark.parametrize("entry", PHOTOS, ids=[_id(e) for e in PHOTOS])
def test_public_photo(entry: dict[str, Any], request: pytest.FixtureRequest) -> None:
    path = STUDY.locate(entry)
    if path is None:
        pytest.fail(f"{entry['file']} not found: it is fetched public data, not in the "
                    "repository (tests/data/kphoto/PROVENANCE.md, 'Where the files are'); "
                    "put the files in a folder and run make photos KPHOTO_DIR=that-folder")
    if entry["expect"] == "pending":
        pytest.fail(f"{entry['file']}: declared but not read yet (expect 'pending'): read it "
                    "once (python -m benchmarks.study_real_photos --set ...) and record the "
                    "outcome in photos.json")
    if entry["expect"] == "miss":
        request.applymarker(pytest.mark.xfail(
            strict=True, reason=entry.get("why", "documented miss, docs/calibration.md")))
    out = STUDY.read_photo(entry, path)
    if entry["expect"] == "refuse":
        assert out.refused is not None, f"read as {out.best_k_s}, expected a refusal"
        assert re.search(entry["refusal"], out.refused), out.refused
        return
    assert out.refused is None, out.refused
    assert out.error_steps is not None
    assert abs(out.error_steps) <= entry["tolerance_steps"] + 1e-6, (
        f"best line {out.best_k_s:.4f} s, judged {entry['judged_k_s']}: "
        f"{out.error_steps:+.1f} steps")
