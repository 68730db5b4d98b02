"""Compensation on the corpus: flow error before/after and the time it takes, per file.

For every corpus file (``--quick``: the three small ones) and the built-in example print,
what a user would run on the twin's default machine: ``compensate(advance=True,
slip=True)``, and where the twin predicts grinding in the original also with the grinding
guard (``guard=True``; advance and slip cannot remove grinding, the guard slows the moves,
at a cost in print time) — also where the compensated file grinds or the pipeline refused
the slip stage as too close to grinding. Both runs are printed for such files; the *user*
run (with the guard where it is needed) is the one the issue's ≥ 5× is checked on.

Every file is also compensated with the flow pacing first (``pace=True``: the path is
slowed where the intended flow would change faster than the melt's lag lets it follow,
:mod:`flowtwin.compensation.pace`), on top of the user run (same guard decision); both
are printed, with the print time before and after and the time the pacing cost.
``FLOWTWIN_BENCH_FILES`` (comma-separated corpus file names) restricts the run to those
files (the machine is shared: the files run one at a time).

Per run: RMS flow error, the per-move peak over-extrusion and the peak over one nozzle
diameter of printed path (:func:`flowtwin.compensation.metrics.window_peak`), before and
after (against the original intent), their improvement factors, grinding moves, the
print-time change and the wall time. The ≥ 5× check uses the RMS and the windowed peak
(see ``docs/compensation.md``); files that miss it are listed at the end.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

from benchmarks import corpus_dir
from flowtwin.compensation import compensate
from flowtwin.gcode.generator import PrintSpec, write_print

HERE = Path(__file__).resolve().parent
QUICK = ("kisslicer_1.1.0.5_thinbox_small.gcode", "bambustudio_1.07_2colour_cube_small.gcode",
         "prusaslicer_2.8.1_minicube_small.gcode")
#: The improvement the issue asks for, on the RMS and the peak.
TARGET = 5.0


def _ratio(a: float, b: float) -> float:
    return a / b if b > 0 else float("inf")


def compensate_file(path: Path, out_dir: Path, *, guard: bool,
                    pace: bool = False) -> dict[str, object]:
    """Compensate one file (advance + slip, the guard and the pacing if asked); figures."""
    dst = out_dir / ("out-" + ("guard-" if guard else "") + ("pace-" if pace else "")
                     + path.name)
    t0 = time.perf_counter()
    report = compensate(path, dst, advance=True, slip=True, guard=guard or None,
                        pace=pace or None)
    wall = time.perf_counter() - t0
    b, a = report.before, report.after
    return {
        "guard": guard, "pace": pace,
        "paced_moves": len(report.paced_moves), "pace_time_cost_s": report.pace_time_cost_s,
        "rms_before": b.rms_flow_error, "rms_after": a.rms_flow_error,
        "rms_x": _ratio(b.rms_flow_error, a.rms_flow_error),
        "peak_before": b.peak_overextrusion, "peak_after": a.peak_overextrusion,
        "peak_x": _ratio(b.peak_overextrusion, a.peak_overextrusion),
        "peak_window_before": b.peak_overextrusion_window,
        "peak_window_after": a.peak_overextrusion_window,
        "peak_window_x": _ratio(b.peak_overextrusion_window, a.peak_overextrusion_window),
        "window_mm": b.window_mm,
        "under_before": b.peak_underextrusion, "under_after": a.peak_underextrusion,
        "added_volume_mm3": report.added_volume_mm3,
        "grinding_before": report.grinding_moves_before,
        "grinding_after": report.grinding_moves_after,
        "slowed_moves": len(report.slowed_moves),
        "time_before_s": report.time_before_s, "time_after_s": report.time_after_s,
        "guard_time_cost_s": report.guard_time_cost_s,
        "lag_factor_changed_moves": report.lag_factor_changed_moves,
        "transformations": list(report.transformations),
        "moves": int(len(b.flow_error)), "lines_rewritten": report.lines_rewritten,
        "wall_s": wall, "warnings": list(report.warnings),
    }


def meets_target(row: dict[str, object]) -> bool:
    """RMS and windowed peak both improved ≥ 5× (a peak already ≤ 0 counts as met)."""
    rms_x = float(row["rms_x"])  # type: ignore[arg-type]
    pk0 = float(row["peak_window_before"])  # type: ignore[arg-type]
    pk_x = float(row["peak_window_x"])  # type: ignore[arg-type]
    return rms_x >= TARGET and (pk0 <= 0.0 or pk_x >= TARGET)


def format_row(name: str, row: dict[str, object]) -> str:
    """One printed line of figures."""
    def pct(v: object) -> str:
        return f"{100 * float(v):7.1f}"  # type: ignore[arg-type]

    def x(v: object) -> str:
        f = float(v)  # type: ignore[arg-type]
        return "   inf" if math.isinf(f) else f"{f:6.1f}"

    t0 = float(row["time_before_s"])  # type: ignore[arg-type]
    t1 = float(row["time_after_s"])  # type: ignore[arg-type]
    time_x = 100.0 * (t1 / t0 - 1.0) if t0 > 0 else 0.0
    cost = float(row.get("pace_time_cost_s", 0.0))  # type: ignore[arg-type]
    pace_note = f"  paced {row['paced_moves']} moves (+{cost:.0f} s)" if row.get("pace") else ""
    tag = ("+guard" if row["guard"] else "") + ("+pace" if row.get("pace") else "")
    return (f"{name[:38]:38s}{tag:11s} RMS {pct(row['rms_before'])} →{pct(row['rms_after'])} % "
            f"({x(row['rms_x'])}×)  peak/move {pct(row['peak_before'])} →"
            f"{pct(row['peak_after'])} % ({x(row['peak_x'])}×)  peak/{row['window_mm']:g} mm "
            f"{pct(row['peak_window_before'])} →{pct(row['peak_window_after'])} % "
            f"({x(row['peak_window_x'])}×)  grind {row['grinding_before']}→"
            f"{row['grinding_after']}  time {t0:7.0f} → {t1:7.0f} s ({time_x:+.1f} %)"
            f"{pace_note}  {float(row['wall_s']):6.1f} s wall"  # type: ignore[arg-type]
            f"{'' if meets_target(row) else '  < 5×'}")


def bench_file(path: Path, out_dir: Path) -> dict[str, object]:
    """Advance + slip; also with the guard where grinding is predicted. Prints both."""
    plain = compensate_file(path, out_dir, guard=False)
    print(format_row(path.name, plain), flush=True)
    entry: dict[str, object] = {"plain": plain, "user": "plain"}
    warned = any("--guard" in str(w) for w in plain["warnings"])  # type: ignore[attr-defined]
    grinds = int(plain["grinding_before"]) + int(plain["grinding_after"])  # type: ignore[call-overload]
    if grinds > 0 or warned:
        guarded = compensate_file(path, out_dir, guard=True)
        print(format_row(path.name, guarded), flush=True)
        entry["guard"] = guarded
        entry["user"] = "guard"
    user = entry[str(entry["user"])]
    assert isinstance(user, dict)
    entry["meets_5x"] = meets_target(user)
    paced = compensate_file(path, out_dir, guard=bool(user["guard"]), pace=True)
    print(format_row(path.name, paced), flush=True)
    entry["paced"] = paced
    entry["meets_5x_paced"] = meets_target(paced)
    return entry


def run(quick: bool = False) -> dict[str, object]:
    files = sorted(corpus_dir().glob("*.gcode"), key=lambda p: p.stat().st_size)
    if quick:
        files = [p for p in files if p.name in QUICK]
    only = [x.strip() for x in os.environ.get("FLOWTWIN_BENCH_FILES", "").split(",")
            if x.strip()]
    if only:
        files = [p for p in files if p.name in only]
    out: dict[str, object] = {}
    missed: list[str] = []
    missed_paced: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        example = Path(tmp) / "example.gcode"
        write_print(example, PrintSpec())
        for path in ([] if only else [example]) + files:
            entry = bench_file(path, Path(tmp))
            out[path.name] = entry
            if not entry["meets_5x"]:
                missed.append(path.name)
            if not entry["meets_5x_paced"]:
                missed_paced.append(path.name)
    n_files = len(out)
    out["below_5x"] = missed
    out["below_5x_paced"] = missed_paced
    print(f"below {TARGET:g}× on RMS or windowed peak (user run): {len(missed)} of "
          f"{n_files}: {', '.join(missed)}")
    print(f"below {TARGET:g}× with the flow pacing: {len(missed_paced)} of {n_files}: "
          f"{', '.join(missed_paced)}")
    return out
