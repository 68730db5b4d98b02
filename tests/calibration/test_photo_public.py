"""Real public photos of printed advance-factor patterns (tests/data/kphoto/photos.json).

Each photo is read with its published layout and compared with the K its author judged
best (tolerance in steps of the pattern, fixed before any photo was read:
PROVENANCE.md). ``expect`` in the manifest says what the reader does with it:

* ``read`` — the best line lies within the tolerance of the nearest judged K;
* ``refuse`` — the reader refuses with the reason given (``refusal`` matches the message);
* ``miss`` — a documented miss (docs/calibration.md): read outside the tolerance; kept
  as a strict expected failure, so a reader that starts getting it right is noticed.

The two OrcaSlicer-wiki photos kept in the repository have their own tests in
test_photo.py. The other photos are not committed (PROVENANCE.md, "Where the files
are"): a photo not found in tests/data/kphoto or ``$FLOWTWIN_KPHOTO_DIR`` is skipped with
that reason.
"""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path
from typing import Any

import pytest


def _study() -> Any:
    # benchmarks/study_real_photos.py holds the manifest reader (also its command line)
    name = "flowtwin_study_real_photos"
    if name not in sys.modules:
        path = Path(__file__).resolve().parents[2] / "benchmarks" / "study_real_photos.py"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


STUDY = _study()
DATA, MANIFEST = STUDY.DATA, STUDY.MANIFEST
PUBLIC = [e for e in STUDY.entries() if not e["in_repo"]]


def test_manifest_declares_split_tolerance_and_source_of_every_photo() -> None:
    photos = json.loads(MANIFEST.read_text())["photos"]
    provenance = (DATA / "PROVENANCE.md").read_text()
    assert {e["split"] for e in photos} == {"dev", "check"}
    for e in photos:
        assert e["file"].split(".")[0].split("-")[0] in provenance
        assert e["judged_k_s"] and all(
            e["params"]["k_start"] - 1e-9 <= k <= e["params"]["k_end"] + 1e-9
            for k in e["judged_k_s"])
        assert 1 <= e["tolerance_steps"] <= 3
        assert e["expect"] in ("read", "refuse", "miss")
        if not e["in_repo"]:
            assert re.fullmatch(r"[0-9a-f]{64}", e["sha256"])
    # the check set holds more independent prints than the development set
    prints = {s: {e["print"] for e in photos if e["split"] == s} for s in ("dev", "check")}
    assert len(prints["check"]) > len(prints["dev"]) and not prints["dev"] & prints["check"]


def _id(e: dict[str, Any]) -> str:
    return f"{e['split']}-{e['file']}"


@pytest.mark.slow
@pytest.mark.parametrize("entry", PUBLIC, ids=[_id(e) for e in PUBLIC])
def test_public_photo(entry: dict[str, Any], request: pytest.FixtureRequest) -> None:
    path = STUDY.locate(entry)
    if path is None:
        pytest.skip(f"{entry['file']} is not in the repository (fetched public data, "
                    "PROVENANCE.md: 'Where the files are'); set FLOWTWIN_KPHOTO_DIR")
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
