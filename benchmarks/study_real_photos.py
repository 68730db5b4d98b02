"""``from-image`` on real photos with the K their authors judged best (not a speed benchmark).

``python -m benchmarks.study_real_photos [--split dev|check|all] [--set NAME] [--dir DIR ...]
[--json]``

Reads ``tests/data/kphoto/photos.json`` (provenance, split and tolerances in
``tests/data/kphoto/PROVENANCE.md``), finds each photo in ``tests/data/kphoto`` or in the
folders given by ``--dir`` (repeatable) or ``$FLOWTWIN_KPHOTO_DIR`` (folders joined by
``os.pathsep``) (its SHA-256 checked), reads it with the photo's
layout and parameters, and prints the best line's error against the nearest judged K, in
steps of the pattern and in s, and the twin's lag. A refusal is listed with its reason.
Photos not present are listed as such. ``--set s9`` reads only the photos of that later
check set (the manifest's ``set``). Figures go to docs/calibration.md.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flowtwin.calibration.fits.kfit import pattern_firmware
from flowtwin.calibration.image.analyse import analyse_line_photo
from flowtwin.calibration.image.chevron_read import analyse_chevron_photo
from flowtwin.calibration.image.layouts import (
    layout_params,
    layout_settings,
    line_layout_pattern,
)
from flowtwin.calibration.patterns.chevron import ChevronParams, chevron_pattern
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.errors import FlowtwinError
from flowtwin.profiles.machine import Machine, load_machine

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "kphoto"
MANIFEST = DATA / "photos.json"
MACHINE = load_machine("tronvoll2019")


@dataclass(frozen=True)
class Outcome:
    """One photo read: error of the best line against the nearest judged K."""

    file: str
    split: str
    pattern: str
    judged_k_s: tuple[float, ...]
    step_s: float
    tolerance_steps: float
    best_k_s: float | None = None
    error_s: float | None = None
    error_steps: float | None = None
    lag_s: float | None = None
    lag_err_s: float | None = None
    refused: str | None = None
    missing: bool = False
    disagreement: float | None = None

    @property
    def within(self) -> bool:
        """Best line within the tolerance (False when refused or missing)."""
        return self.error_steps is not None and abs(self.error_steps) <= \
            self.tolerance_steps + 1e-6


def entries(split: str = "all", photo_set: str | None = None) -> list[dict[str, Any]]:
    """The manifest's photos of one split (``dev``, ``check`` or ``all``), optionally only
    those of one later check set (``"set"`` in the manifest, e.g. ``s9``)."""
    photos: list[dict[str, Any]] = json.loads(MANIFEST.read_text())["photos"]
    return [p for p in photos if (split == "all" or p["split"] == split)
            and (photo_set is None or p.get("set") == photo_set)]


def folders(folder: str | os.PathLike[str] | list[str] | None = None) -> list[Path]:
    """Where photos are looked for: ``tests/data/kphoto``, then ``folder`` (one path, a
    list, or paths joined by ``os.pathsep``), else ``$FLOWTWIN_KPHOTO_DIR`` (likewise)."""
    given: list[str]
    if folder is None:
        given = [os.environ.get("FLOWTWIN_KPHOTO_DIR", "")]
    elif isinstance(folder, list):
        given = folder
    else:
        given = [os.fspath(folder)]
    return [DATA] + [Path(part) for g in given for part in g.split(os.pathsep) if part]


def locate(entry: dict[str, Any],
           folder: str | os.PathLike[str] | list[str] | None = None) -> Path | None:
    """The photo's file (SHA-256 checked when the manifest gives one), or ``None``."""
    for d in folders(folder):
        path = d / entry["file"]
        if path.is_file():
            want = entry.get("sha256")
            if want and hashlib.sha256(path.read_bytes()).hexdigest() != want:
                raise ValueError(f"{path}: SHA-256 differs from photos.json ({want})")
            return path
    return None


def pattern_of(entry: dict[str, Any], machine: Machine = MACHINE) -> Pattern:
    """The pattern as printed, from the manifest entry."""
    params = dict(entry["params"])
    base = PrintSettings(firmware=pattern_firmware(machine),
                         accel_mm_s2=float(entry["accel_mm_s2"]),
                         line_width_mm=float(entry.get("line_width_mm", 0.48)))
    if entry["pattern"] == "chevron":
        return chevron_pattern(base, ChevronParams(**params))
    s = layout_settings(entry["pattern"], base, line_width_given="line_width_mm" in entry,
                        accel_given=True)
    return line_layout_pattern(entry["pattern"], s, layout_params(entry["pattern"], params))


def read_photo(entry: dict[str, Any], path: Path, machine: Machine = MACHINE) -> Outcome:
    """Read one photo and compare its best line with the judged K."""
    judged = tuple(float(k) for k in entry["judged_k_s"])
    step = float(entry["params"]["k_step"])
    base = Outcome(entry["file"], entry["split"], entry["pattern"], judged, step,
                   float(entry["tolerance_steps"]))
    pat = pattern_of(entry, machine)
    try:
        if entry["pattern"] == "chevron":
            res: Any = analyse_chevron_photo(path, pat, machine=machine)
        else:
            res = analyse_line_photo(path, pat, machine=machine)
    except FlowtwinError as exc:
        z = exc.value.get("z") if isinstance(exc.value, dict) else None
        return _replace(base, refused=str(exc), disagreement=z)
    best = float(res.k_best_line_s)
    errs = [best - k for k in judged]
    err = min(errs, key=abs)
    lag = res.lag
    return _replace(base, best_k_s=best, error_s=err, error_steps=err / step,
                    lag_s=None if lag is None else float(lag.k_s),
                    lag_err_s=None if lag is None else float(lag.k_err_s),
                    disagreement=float(res.disagreement) if np.isfinite(res.disagreement)
                    else None)


def _replace(o: Outcome, **kw: Any) -> Outcome:
    return Outcome(**{**asdict(o), **kw})


def summary(outcomes: list[Outcome]) -> dict[str, Any]:
    """Median and worst |error| of the photos read, in steps and in s; refusals."""
    read = [o for o in outcomes if o.error_steps is not None]
    e_steps = np.array([o.error_steps for o in read], dtype=float)
    e_s = np.array([o.error_s for o in read], dtype=float)
    out: dict[str, Any] = {"read": len(read),
                           "refused": sum(o.refused is not None for o in outcomes),
                           "missing": sum(o.missing for o in outcomes),
                           "within_tolerance": sum(o.within for o in read)}
    if read:
        worst = int(np.argmax(np.abs(e_steps)))
        out.update(median_abs_steps=float(np.median(np.abs(e_steps))),
                   worst_steps=float(e_steps[worst]),
                   median_abs_s=float(np.median(np.abs(e_s))), worst_s=float(e_s[worst]),
                   worst_file=read[worst].file)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", default="all", choices=("dev", "check", "all"))
    ap.add_argument("--set", default=None, dest="photo_set",
                    help="only the photos of this later check set (manifest 'set', e.g. s9)")
    ap.add_argument("--dir", action="append", default=None,
                    help="folder holding photos not in the repo (repeatable)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    outcomes = []
    for e in entries(a.split, a.photo_set):
        print(f"reading {e['file']}", file=sys.stderr, flush=True)
        path = locate(e, a.dir)
        if path is None:
            outcomes.append(Outcome(e["file"], e["split"], e["pattern"],
                                    tuple(e["judged_k_s"]), float(e["params"]["k_step"]),
                                    float(e["tolerance_steps"]), missing=True))
            continue
        o = read_photo(e, path)
        outcomes.append(o)
        if not a.json:
            if o.refused:
                print(f"{o.file:28s} {o.pattern:12s} REFUSED: {o.refused}", flush=True)
            else:
                lag = "-" if o.lag_s is None else f"{o.lag_s:.4f}±{o.lag_err_s:.4f}"
                print(f"{o.file:28s} {o.pattern:12s} judged {list(o.judged_k_s)} best "
                      f"{o.best_k_s:.4f} error {o.error_s:+.4f} s ({o.error_steps:+.1f} "
                      f"steps) lag {lag} {'ok' if o.within else 'MISS'}", flush=True)
    s = summary(outcomes)
    if a.json:
        json.dump({"photos": [asdict(o) for o in outcomes], "summary": s}, sys.stdout,
                  indent=1)
        print()
    else:
        print(json.dumps(s))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
