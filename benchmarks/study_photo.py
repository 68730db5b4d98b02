"""Accuracy study of ``from-image`` on the independent renderer (not a speed benchmark).

``python -m benchmarks.study_photo [--n 32] [--seed 0] [--layouts a,b] [--out FILE]``

Renders ``n`` photos with :mod:`flowtwin.calibration.image.photosynth` (its own speed
profile, advance and lag model and camera: nothing of the planner or the twin), each with
a true lag ``τ`` drawn between the pattern's lines (not on a line), and conditions drawn
from ranges a phone photo spans: every layout, light and dark beads, textured / patterned
/ smooth sheets, perspective (tilt 0–10°), any rotation, light falling off, gloss, blur
0.5–1.6 px, JPEG 60–95, 7–12 px/mm. Each is analysed with
:func:`flowtwin.calibration.image.analyse.analyse_line_photo` (chevrons with
:func:`flowtwin.calibration.image.chevron_read.analyse_chevron_photo`) and compared with
``τ``: the best line's K (in s and in steps), the zero crossings and the twin's lag.
Refusals are counted with their reason (a refusal is not an error; a confident wrong
answer is).

Not part of ``make bench`` (minutes, not a timing); figures go to docs/calibration.md.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from flowtwin.calibration.fits.kfit import kline_for_machine, pattern_firmware
from flowtwin.calibration.image.analyse import analyse_line_photo
from flowtwin.calibration.image.layouts import (
    layout_params,
    layout_settings,
    line_layout_pattern,
)
from flowtwin.calibration.image.photosynth import (
    PhotoConditions,
    render_photo,
    scene_from_pattern,
)
from flowtwin.calibration.patterns.chevron import ChevronParams, chevron_pattern
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.errors import FlowtwinError
from flowtwin.profiles.machine import load_machine

MACHINE = load_machine("tronvoll2019")
ACCEL = 1000.0
LAYOUTS = ("kline", "marlin", "prusa", "orca", "orca-legacy", "pa-camera", "chevron")

#: K range of each layout's renders: (start, end, step), s.
K_RANGE = {"kline": (0.0, 0.1, 0.01), "marlin": (0.0, 0.1, 0.01), "prusa": (0.0, 0.1, 0.01),
           "orca": (0.0, 0.08, 0.008), "orca-legacy": (0.0, 0.08, 0.008),
           "pa-camera": (0.0, 0.1, 0.01), "chevron": (0.0, 0.1, 0.01)}


@dataclass(frozen=True)
class Case:
    """One render of the study."""

    index: int
    layout: str
    lag_s: float
    k_step_s: float
    conditions: PhotoConditions


def make_pattern(layout: str) -> Pattern:
    """The layout's pattern over its study K range, for the study's machine."""
    k0, k1, dk = K_RANGE[layout]
    base = PrintSettings(firmware=pattern_firmware(MACHINE), accel_mm_s2=ACCEL)
    if layout == "kline":
        return kline_for_machine(MACHINE, base, KLineParams(k_start=k0, k_end=k1, k_step=dk))
    if layout == "chevron":
        return chevron_pattern(base, ChevronParams(k_start=k0, k_end=k1, k_step=dk))
    s = layout_settings(layout, base, accel_given=True)
    return line_layout_pattern(layout, s, layout_params(
        layout, {"k_start": k0, "k_end": k1, "k_step": dk}))


def draw_cases(n: int, seed: int, layouts: tuple[str, ...]) -> list[Case]:
    """``n`` cases, layouts in turn, conditions drawn from the study's ranges."""
    out = []
    for i in range(n):
        rng = np.random.default_rng(seed * 1000 + i)
        layout = layouts[i % len(layouts)]
        k0, k1, dk = K_RANGE[layout]
        # a lag between the lines, away from the range's ends by two steps
        lag = float(rng.uniform(k0 + 2 * dk, k1 - 2 * dk))
        light = bool(rng.random() < 0.6)
        if light:
            bead = tuple(int(v) for v in rng.integers(190, 250, 3))
            sheet = tuple(int(v) for v in rng.integers(20, 90, 3))
        else:
            bead = tuple(int(v) for v in rng.integers(15, 90, 3))
            sheet = tuple(int(v) for v in rng.integers(150, 230, 3))
        kind = str(rng.choice(["textured", "patterned", "smooth"], p=[0.5, 0.25, 0.25]))
        cond = PhotoConditions(
            px_per_mm=float(rng.uniform(7.0, 12.0)), tilt_deg=float(rng.uniform(0.0, 10.0)),
            tilt_axis_deg=float(rng.uniform(0.0, 180.0)),
            roll_deg=float(rng.uniform(-180.0, 180.0)), light_beads=light,
            bead_bgr=bead, sheet_bgr=sheet, sheet=kind,  # type: ignore[arg-type]
            texture=float(rng.uniform(0.05, 0.3)) if light else float(rng.uniform(0.02, 0.08)),
            gloss=float(rng.uniform(0.0, 0.3)), falloff=float(rng.uniform(0.0, 0.5)),
            label=bool(rng.random() < 0.7), blur_px=float(rng.uniform(0.5, 1.6)),
            read_noise=float(rng.uniform(1.0, 5.0)), jpeg_quality=int(rng.integers(60, 96)),
            seed=seed * 1000 + i)
        out.append(Case(i, layout, lag, dk, cond))
    return out


def analyse_case(case: Case, method: str = "area") -> dict[str, Any]:
    """Render and read one case; its errors or its refusal."""
    pat = make_pattern(case.layout)
    marks, tests = scene_from_pattern(pat, lag_s=case.lag_s, accel_mm_s2=ACCEL)
    photo = render_photo(pat, marks, tests, case.conditions)
    row: dict[str, Any] = {"index": case.index, "layout": case.layout, "lag_s": case.lag_s,
                           "k_step_s": case.k_step_s,
                           "conditions": asdict(case.conditions)}
    t0 = time.perf_counter()
    try:
        if case.layout == "chevron":
            from flowtwin.calibration.image.chevron_read import analyse_chevron_photo
            res: Any = analyse_chevron_photo(photo.image, pat, machine=MACHINE)
        else:
            res = analyse_line_photo(photo.image, pat, machine=MACHINE, method=method)
    except FlowtwinError as exc:
        row.update(refused=str(exc), seconds=time.perf_counter() - t0)
        if isinstance(exc.value, dict) and "z" in exc.value:   # an answer check refused
            row.update(answers=exc.value)
        return row
    best = res.k_best_line_s
    row.update(refused=None, seconds=time.perf_counter() - t0, k_best_line_s=best,
               best_error_s=best - case.lag_s,
               best_error_steps=(best - case.lag_s) / case.k_step_s,
               k_cross_s=getattr(res, "k_cross_s", None),
               best_by=getattr(res, "best_by", None),
               lag_fit_s=None if res.lag is None else res.lag.k_s,
               lag_fit_err_s=None if res.lag is None else res.lag.k_err_s,
               lag_problem=res.lag_problem, reading=res.reading,
               disagreement=_finite(res.disagreement))
    if row["k_cross_s"] is not None:
        row["cross_error_s"] = row["k_cross_s"] - case.lag_s
    if res.lag is not None:
        row["lag_error_s"] = res.lag.k_s - case.lag_s
    return row


def _finite(x: float) -> float | None:
    return x if math.isfinite(x) else None


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Median and worst of each error over the answered cases; refusals counted."""
    answered = [r for r in rows if r["refused"] is None]

    def stats(key: str) -> dict[str, float | int | None]:
        v = np.array([r[key] for r in answered if r.get(key) is not None], dtype=float)
        if v.size == 0:
            return {"n": 0, "median": None, "median_abs": None, "worst": None}
        return {"n": int(v.size), "median": float(np.median(v)),
                "median_abs": float(np.median(np.abs(v))),
                "worst": float(v[int(np.argmax(np.abs(v)))])}

    # half a step is the resolution of a best line when the lag lies between two lines
    within_half = [abs(r["best_error_steps"]) <= 0.5 + 1e-9 for r in answered]
    within_one = [abs(r["best_error_steps"]) <= 1.0 + 1e-9 for r in answered]
    return {"renders": len(rows), "answered": len(answered),
            "refused": {str(r["index"]): r["refused"] for r in rows if r["refused"]},
            "best_line_error_s": stats("best_error_s"),
            "best_line_error_steps": stats("best_error_steps"),
            "best_line_nearest": int(sum(within_half)),
            "best_line_within_one_step": int(sum(within_one)),
            "crossing_error_s": stats("cross_error_s"),
            "lag_error_s": stats("lag_error_s"),
            "lag_fit_failed": int(sum(r["lag_fit_s"] is None for r in answered))}


def _fmt(x: float | None, digits: int = 4) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.study_photo",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=32)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--layouts", default=",".join(LAYOUTS))
    ap.add_argument("--only", default="", help="comma-separated case indices")
    ap.add_argument("--out", default="")
    ap.add_argument("--method", default="area", help="width measurement (line layouts)")
    args = ap.parse_args(argv)
    layouts = tuple(x for x in args.layouts.split(",") if x)
    cases = draw_cases(args.n, args.seed, layouts)
    if args.only:
        keep = {int(x) for x in args.only.split(",")}
        cases = [c for c in cases if c.index in keep]
    rows = []
    print(f"{'#':>3} {'layout':12} {'lag':>7} {'best':>7} {'steps':>6} {'cross':>7} "
          f"{'twin':>7} {'±':>7} {'s':>4}  conditions / refusal", flush=True)
    for case in cases:
        row = analyse_case(case, args.method)
        rows.append(row)
        c = case.conditions
        what = (f"{c.px_per_mm:.1f}px/mm tilt {c.tilt_deg:.0f} roll {c.roll_deg:.0f} "
                f"{'light' if c.light_beads else 'dark'} {c.sheet} tex {c.texture:.2f} "
                f"gloss {c.gloss:.2f} fall {c.falloff:.2f} blur {c.blur_px:.1f} "
                f"jpeg {c.jpeg_quality}")
        if row["refused"]:
            print(f"{case.index:3d} {case.layout:12} {case.lag_s:7.4f} {'refused':>7} "
                  f"{'':6} {'':7} {'':7} {'':7} {row['seconds']:4.0f}  {what}: "
                  f"{row['refused']}", flush=True)
            continue
        print(f"{case.index:3d} {case.layout:12} {case.lag_s:7.4f} {row['k_best_line_s']:7.4f} "
              f"{row['best_error_steps']:+6.2f} {_fmt(row['k_cross_s'])} "
              f"{_fmt(row['lag_fit_s'])} {_fmt(row['lag_fit_err_s'])} {row['seconds']:4.0f}  "
              f"{what}", flush=True)
    summary = summarise(rows)
    print(json.dumps(summary, indent=1))
    if args.out:
        with open(args.out, "w") as fh:
            json.dump({"summary": summary, "rows": rows}, fh, indent=1, default=str)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
