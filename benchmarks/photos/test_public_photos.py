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


def test_qidi_gold_sheet_with_its_overlay_inpainted_is_refused() -> None:
    """Session 13's follow-up, held (docs/calibration.md, "Session 17"; a known case, not
    a blind check): the QIDI wizard's gold-sheet photo, read as a photo of the top, with
    the author's red box inpainted away (OpenCV, a 5-px-dilated mask of the red pixels).
    Its scores are then flat, the errors do not cross in the range and no lag can be
    fitted: before session 17 the reader answered 0.022 s (judged 0.03 s, −2 steps); now
    it refuses."""
    import cv2
    import numpy as np

    from flowtwin.calibration.image.analyse import analyse_line_photo
    from flowtwin.errors import VisionError

    entry = next(e for e in PHOTOS if e["file"] == "qidi-pa-lines-gold.png")
    path = STUDY.locate(entry)
    if path is None:
        pytest.fail(f"{entry['file']} not found (tests/data/kphoto/PROVENANCE.md)")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    b, g, r = (img[..., i].astype(np.int32) for i in range(3))
    red = ((r > 150) & (g < 100) & (b < 100)).astype(np.uint8) * 255
    assert 0.01 < np.count_nonzero(red) / red.size < 0.05       # the box, and little else
    mask = cv2.dilate(red, np.ones((5, 5), np.uint8))
    clean = cv2.inpaint(img, mask, 5, cv2.INPAINT_TELEA)
    with pytest.raises(VisionError, match="only the smallest score picks the best line") as exc:
        analyse_line_photo(clean, STUDY.pattern_of(entry), machine=STUDY.MACHINE, view="top")
    assert "lag could not be fitted" in exc.value.message
