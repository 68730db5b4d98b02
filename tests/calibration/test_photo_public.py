"""Real public photos of printed advance-factor patterns (tests/data/kphoto/photos.json).

Each photo is read with its published layout and compared with the K its author judged
best (tolerance in steps of the pattern, fixed before any photo was read:
PROVENANCE.md). ``expect`` in the manifest says what the reader does with it:

* ``read`` — the best line lies within the tolerance of the nearest judged K;
* ``refuse`` — the reader refuses with the reason given (``refusal`` matches the message);
* ``miss`` — a documented miss (docs/calibration.md): read outside the tolerance; kept
  as a strict expected failure, so a reader that starts getting it right is noticed;
* ``pending`` — declared (judged K, layout, tolerance committed) but not read yet; only
  between a new check set's declaration and its one reading.

The photos themselves are not committed (PROVENANCE.md, "Where the files are"); the
readings are checked by ``make photos`` (benchmarks/photos/test_public_photos.py). This
file checks the manifest those readings are held to.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data" / "kphoto"
MANIFEST = DATA / "photos.json"


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
        assert e["expect"] in ("read", "refuse", "miss", "pending")
        if e["expect"] == "refuse":
            assert e["refusal"]
        if "set" in e:      # a later check set is never a development set
            assert e["split"] == "check"
        if not e["in_repo"]:
            assert re.fullmatch(r"[0-9a-f]{64}", e["sha256"])
    # the check set holds more independent prints than the development set
    prints = {s: {e["print"] for e in photos if e["split"] == s} for s in ("dev", "check")}
    assert len(prints["check"]) > len(prints["dev"]) and not prints["dev"] & prints["check"]
