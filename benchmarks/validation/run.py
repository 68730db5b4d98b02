"""Compensate the validation prints and report the spread of the improvement.

    python -m benchmarks.validation.run --split dev|check|check2|check3|check4|check5|check6
                                        [--pace [--everywhere] [--pull-ratio R]
                                        [--spots ERROR] [--budget PCT | --no-budget]]
                                        [--slip]
                                        [--only SUBSTR]

For every print of the split (made by :mod:`benchmarks.validation.generate` first when
missing), ``compensate(advance=True)`` (``--pace``: also the flow pacing, near the spots the advance
leaves; ``--everywhere``: at every junction, without the pull-back, as before the spots;
``--pull-ratio``, ``--spots``: ``PaceOptions.pull_ratio``, ``spot_error``; ``--budget``:
``PaceOptions.time_budget`` in percent, ``--no-budget``: none; ``--slip``: also
the slip feed-forward) on the
print's machine; per print the RMS flow error and the peak
over-extrusion over one nozzle diameter of path before and after, their improvement
factors, the print time before and after and the wall time; then the median and the worst
of both factors and the prints below 5x; with ``--pace`` also the print time the pacing
added (planned, ``pace_time_cost_s`` over the print time before) and its spots (found,
paced, left by the budget). Results go to ``out/results-SPLIT[-pace].json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import statistics
import sys
import tempfile
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from benchmarks.validation.generate import OUT, generate, machine_of
from benchmarks.validation.prints import PRINTS, SPLITS, Print

if TYPE_CHECKING:
    from flowtwin.compensation import CompensationReport
    from flowtwin.compensation.pace import PaceOptions

TARGET = 5.0


def _ratio(a: float, b: float) -> float:
    return a / b if b > 0 else math.inf


def pace_options(*, everywhere: bool, pull_ratio: float | None,
                 spot_error: float | None, budget: float | str | None = "default"
                 ) -> PaceOptions:
    """``PaceOptions()`` (near the spots), or everywhere without the pull-back (as before
    the spots), with the ratio, the spot error and the time budget (a share; ``None``: no
    cap; ``"default"``: the default) given."""
    from flowtwin.compensation.pace import PaceOptions

    o = PaceOptions(spots=False, pull_ratio=0.0) if everywhere else PaceOptions()
    if pull_ratio is not None:
        o = replace(o, pull_ratio=pull_ratio)
    if budget != "default":
        o = replace(o, time_budget=budget)
    return o if spot_error is None else replace(o, spot_error=spot_error)


def run_print(p: Print, out: Path, *, pace: PaceOptions | None, slip: bool
              ) -> dict[str, object]:
    """Compensate one print; its figures."""
    from flowtwin.compensation import compensate

    machine, cfg = machine_of(p, out)
    src = out / f"{p.name}.gcode"
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        report = compensate(src, Path(tmp) / "out.gcode", machine=machine, klipper_config=cfg,
                            advance=True, pace=pace, slip=slip or None)
        wall = time.perf_counter() - t0
    b, a = report.before, report.after
    floor = volume_floor(report)
    return {
        "name": p.name, "split": p.split, "paced": pace is not None, "slip": slip,
        "pace_options": None if pace is None else asdict(pace),
        "rms_before": b.rms_flow_error, "rms_after": a.rms_flow_error,
        "rms_x": _ratio(b.rms_flow_error, a.rms_flow_error),
        "window_before": b.peak_overextrusion_window,
        "window_after": a.peak_overextrusion_window,
        "window_x": _ratio(b.peak_overextrusion_window, a.peak_overextrusion_window),
        "rms_floor_after": floor, "rms_x_bound": _ratio(b.rms_flow_error, floor),
        "time_before_s": report.time_before_s, "time_after_s": report.time_after_s,
        "time_cost": report.time_after_s / report.time_before_s - 1.0,
        "pace_cost": report.pace_time_cost_s / report.time_before_s,
        "pace": None if report.pace is None else report.pace.as_dict(),
        "transformations": list(report.transformations), "wall_s": wall,
        "warnings": list(report.warnings),
    }


#: Content hash of every slice the documented figures were measured on (session 13's
#: tables): PrusaSlicer 2.5 does not write the same G-code twice, so a fresh slice may give
#: other figures (docs/compensation.md, "The slices are not reproducible bit for bit").
SLICES = Path(__file__).resolve().parent / "SLICES.tsv"


def slice_hash(path: Path) -> str:
    """SHA-256 of a G-code's lines that are not comments (a slicer's time stamp and
    settings block do not count)."""
    h = hashlib.sha256()
    with path.open("rb") as f:
        for line in f:
            if not line.lstrip().startswith(b";"):
                h.update(line)
    return h.hexdigest()


def documented_slices() -> dict[str, str]:
    """Print name → content hash of the slice the documented figures used."""
    if not SLICES.exists():
        return {}
    rows = (ln.split("\t") for ln in SLICES.read_text().splitlines() if ln and ln[0] != "#")
    return {name: digest for name, digest in rows}


def volume_floor(report: CompensationReport) -> float:
    """The least RMS flow error a file delivering the volume ``report``'s result delivers
    can have: ``|Σ w·e| / Σ w`` over the extruding moves (``w`` the intended volume, ``e``
    the relative flow error of the result), by the Cauchy–Schwarz inequality
    ``Σ w·e² / Σ w ≥ (Σ w·e / Σ w)²``. An advance keeps the file's volume, so what the
    drive slips on average stays in its error: with the advance alone the RMS flow error
    cannot fall below this (up to the slip's small change with the advance's force
    profile)."""
    from flowtwin.compensation.metrics import Intent, extruding_moves

    original = report.original_result
    if original is None:
        return math.nan
    intent = Intent.of(original, window_mm=report.before.window_mm)
    ext = extruding_moves(intent)
    w = np.asarray(intent.cmd_mm3, dtype=np.float64)[ext]
    e = np.asarray(report.after.flow_error, dtype=np.float64)[ext]
    return float(abs(np.sum(w * e)) / np.sum(w)) if np.sum(w) > 0 else 0.0


def _spots(r: dict[str, object]) -> str:
    """``paced/found (left by the budget)`` of a row's pacing."""
    p = r.get("pace")
    if not isinstance(p, dict):
        return "-"
    return f"{p['spots_paced']}/{p['spots']}" + (f" -{p['spots_over_budget']}"
                                                 if p["spots_over_budget"] else "")


def summarise(rows: list[dict[str, object]]) -> dict[str, float]:
    """Median and worst of both improvement factors, and the share of prints at 5x."""
    rms = [float(r["rms_x"]) for r in rows]  # type: ignore[arg-type]
    win = [float(r["window_x"]) for r in rows]  # type: ignore[arg-type]
    cost = [float(r["time_cost"]) for r in rows]  # type: ignore[arg-type]
    pace = [float(r["pace_cost"]) for r in rows]  # type: ignore[arg-type]
    ok = [r_ >= TARGET and w >= TARGET for r_, w in zip(rms, win, strict=True)]
    bound = [float(r["rms_x_bound"]) for r in rows]  # type: ignore[arg-type]
    return {"prints": len(rows), "rms_median": statistics.median(rms), "rms_worst": min(rms),
            "window_median": statistics.median(win), "window_worst": min(win),
            "time_cost_median": statistics.median(cost), "time_cost_worst": max(cost),
            "pace_cost_median": statistics.median(pace), "pace_cost_worst": max(pace),
            "at_target": sum(ok),
            "bound_below_target": sum(b_ < TARGET for b_ in bound)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=SPLITS, required=True)
    parser.add_argument("--pace", action="store_true")
    parser.add_argument("--slip", action="store_true")
    parser.add_argument("--everywhere", action="store_true",
                        help="with --pace: pace every junction the envelopes name, without "
                             "the pull-back (the pacing before the spots)")
    parser.add_argument("--pull-ratio", type=float, default=None,
                        help="PaceOptions.pull_ratio with --pace")
    parser.add_argument("--spots", type=float, default=None, metavar="ERROR",
                        help="PaceOptions.spot_error with --pace")
    parser.add_argument("--budget", type=float, default=None, metavar="PCT",
                        help="PaceOptions.time_budget with --pace, percent of the print time")
    parser.add_argument("--no-budget", action="store_true",
                        help="with --pace: no time budget (PaceOptions.time_budget None)")
    parser.add_argument("--only", help="run the prints whose name contains this")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    prints = [p for p in PRINTS if p.split == args.split
              and (args.only is None or args.only in p.name)]
    if any(not (args.out / f"{p.name}.gcode").exists() for p in prints):
        generate(args.split, args.out)
    rows = []
    known = documented_slices()
    other = [p.name for p in prints
             if p.name in known and slice_hash(args.out / f"{p.name}.gcode") != known[p.name]]
    if other:
        print(f"note: {len(other)} of {len(prints)} slices differ from the ones the documented "
              f"figures were measured on ({SLICES.name}; PrusaSlicer 2.5 does not slice the "
              "same twice): expect their figures to differ a little")
    print(f"{'print':<72} {'RMS before→after':>20} {'×':>6} {'peak/0.4mm':>20} {'×':>6} "
          f"{'time':>7} {'pace':>7} {'spots':>11} {'wall':>6}")
    for p in prints:
        budget: float | str | None = (None if args.no_budget else "default"
                                      if args.budget is None else args.budget / 100.0)
        pace = pace_options(everywhere=args.everywhere, pull_ratio=args.pull_ratio,
                            spot_error=args.spots, budget=budget) if args.pace else None
        r = run_print(p, args.out, pace=pace, slip=args.slip)
        rows.append(r)
        print(f"{p.name:<72} {100 * float(r['rms_before']):8.2f} → "  # type: ignore[arg-type]
              f"{100 * float(r['rms_after']):6.2f} % {float(r['rms_x']):6.1f} "  # type: ignore[arg-type]
              f"{100 * float(r['window_before']):8.1f} → "  # type: ignore[arg-type]
              f"{100 * float(r['window_after']):6.1f} % {float(r['window_x']):6.1f} "  # type: ignore[arg-type]
              f"{100 * float(r['time_cost']):+6.1f}% "  # type: ignore[arg-type]
              f"{100 * float(r['pace_cost']):+6.1f}% {_spots(r):>11} "  # type: ignore[arg-type]
              f"{float(r['wall_s']):5.1f}s  bound {float(r['rms_x_bound']):5.1f}",  # type: ignore[arg-type]
              flush=True)
    s = summarise(rows)
    print(f"\n{args.split}{' + pace' if args.pace else ''}: {s['prints']} prints, RMS x median "
          f"{s['rms_median']:.1f} worst {s['rms_worst']:.1f}; windowed peak x median "
          f"{s['window_median']:.1f} worst {s['window_worst']:.1f}; print time "
          f"{100 * s['time_cost_median']:+.1f} % median, {100 * s['time_cost_worst']:+.1f} % "
          f"worst; pacing's time {100 * s['pace_cost_median']:+.1f} % median, "
          f"{100 * s['pace_cost_worst']:+.1f} % worst; {s['at_target']} of {s['prints']} at "
          f"{TARGET:g}x on both; on {s['bound_below_target']} the volume delivered bounds "
          f"the RMS factor below {TARGET:g}x")
    tag = (args.split + ("-pace" if args.pace else "")
           + ("-everywhere" if args.pace and args.everywhere else "")
           + (f"-pull{args.pull_ratio:g}" if args.pace and args.pull_ratio is not None else "")
           + (f"-spots{args.spots:g}" if args.pace and args.spots is not None else "")
           + ("-nobudget" if args.pace and args.no_budget else "")
           + (f"-budget{args.budget:g}" if args.pace and args.budget is not None else "")
           + ("-slip" if args.slip else ""))
    if args.only is None:
        (args.out / f"results-{tag}.json").write_text(
            json.dumps({"summary": s, "prints": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
