"""[003] Greeff, Schilling 2017: slip in filament transport — claims and figures.

Steady slip of Greeff's set-up (RF1000, 0.5 mm nozzle, 2.85 mm PLA, free extrusion) from
:func:`flowtwin.physics.operating_point.setup_steady_feed`: the nozzle's pressure drop at the
nominal feed sets the feed force, and Eq. 6 of [000] with the drive defaults
(:data:`flowtwin.physics.defaults.GREEFF_RF1000`, calibrated to the ~10 % at 215 °C of
[003 §3.1]) turns it into slip. The closed-loop print-job test of [003 §3.3] runs on the
fully simulated loop (:mod:`flowtwin.reproduce.greeff2017_printjob`).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from flowtwin.physics.defaults import GREEFF_RF1000
from flowtwin.physics.operating_point import setup_steady_feed
from flowtwin.reproduce.claims import Claim, Outcome, RowKind, rounded, within_abs
from flowtwin.reproduce.context import ReproContext
from flowtwin.reproduce.figures import FigureSpec, PaperSection
from flowtwin.reproduce.greeff2017_printjob import CLAIMS as PRINT_JOB_CLAIMS
from flowtwin.reproduce.greeff2017_printjob import PRINT_JOB_FIGURE
from flowtwin.reproduce.greeff2017_printjob import notes as print_job_notes
from flowtwin.teststand.figures import new_figure

__all__ = ["SECTION"]

PAPER = "greeff2017"
_ENGINE = "flowtwin.physics.operating_point.setup_steady_feed"
#: Temperatures of [003 §3.1]: 185-230 °C in 5 °C steps.
TEMPS_C = tuple(float(t) for t in range(185, 231, 5))
#: The feed speeds of [003] (1 mm/s first layer, 1.5 mm/s, 2 mm/s set point).
SPEEDS_MM_S = (1.0, 1.5, 2.0)


def slip_table() -> np.ndarray:
    """Steady slip, %, shape (len(SPEEDS_MM_S), len(TEMPS_C))."""
    return np.array([[100.0 * setup_steady_feed(GREEFF_RF1000, v, temp_c=t).slip
                      for t in TEMPS_C] for v in SPEEDS_MM_S])


def _at_215(ctx: ReproContext) -> Outcome:
    s = 100.0 * setup_steady_feed(GREEFF_RF1000, 2.0, temp_c=215.0).slip
    return within_abs(10.0, s, 3.0, unit="percentage points",
                      why="'around 10 %' for three filaments; Fig. 6 scatters by several %",
                      note="2 mm/s feed [003 Fig. 4], 215 °C, steady state; the drive's "
                           "pinch force (rf1000-gear) was set so that this row holds")


def _trend_temperature(ctx: ReproContext) -> Outcome:
    table = slip_table()
    ok = bool(np.all(np.diff(table, axis=1) < 0.0))
    return Outcome("slip increases with decreasing temperature",
                   rounded([table[-1, 0], table[-1, -1]], 3),
                   "strictly decreasing over 185-230 °C at 1, 1.5 and 2 mm/s", ok,
                   "slip (%) at 185 °C and 230 °C, 2 mm/s")


def _trend_speed(ctx: ReproContext) -> Outcome:
    table = slip_table()
    ok = bool(np.all(np.diff(table, axis=0) > 0.0))
    i = TEMPS_C.index(215.0)
    return Outcome("slip increases with extrusion speed", rounded(table[:, i].tolist(), 3),
                   "strictly increasing from 1 to 2 mm/s at every temperature", ok,
                   "slip (%) at 1, 1.5, 2 mm/s, 215 °C")


CLAIMS: tuple[Claim, ...] = (
    Claim(PAPER, "slip-215c", "Under-extrusion of around 10 % at the recommended 215 °C",
          "[003 §3.1]", _at_215, unit="%", figure="slip", kind=RowKind.ANCHOR,
          engine=_ENGINE),
    Claim(PAPER, "slip-vs-temperature", "Slippage increases with decreasing temperature",
          "[003 §3.1, Fig. 6]", _trend_temperature, unit="%", figure="slip", engine=_ENGINE),
    Claim(PAPER, "slip-vs-speed", "Slippage increases with extrusion speed",
          "[003 §3.1, Fig. 6]", _trend_speed, unit="%", figure="slip", engine=_ENGINE),
    *PRINT_JOB_CLAIMS,
)


def _fig_slip(ctx: ReproContext) -> Figure:
    table = slip_table()
    fig, (ax,) = new_figure(6.4, 4.0)
    for v, row in zip(SPEEDS_MM_S, table, strict=True):
        ax.plot(TEMPS_C, row, "o-", label=f"{v:g} mm/s")
    ax.axhline(10.0, color="0.6", ls=":", lw=1)
    ax.annotate("~10 % at 215 °C [003]", (215.0, 10.0), (217.0, 17.0),
                arrowprops={"arrowstyle": "->"}, fontsize=8)
    ax.set_xlabel("nozzle temperature (°C)")
    ax.set_ylabel("steady slip (%)")
    ax.set_title("Greeff's RF1000 set-up, 2.85 mm PLA (Fig. 6 style)")
    ax.legend(fontsize=8)
    return fig


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("slip", "[003 Fig. 6] steady slip against temperature at three feed speeds "
                       "(flowtwin's nozzle and drive models, Greeff's set-up).", _fig_slip),
    PRINT_JOB_FIGURE,
)


def notes(ctx: ReproContext) -> list[str]:
    """Findings beyond the rows: failure below 200 °C is not predicted in steady state."""
    s190 = setup_steady_feed(GREEFF_RF1000, 2.0, temp_c=190.0)
    return [
        f"[003] saw extrusion fail (the gear cutting into the filament) below about 200 °C. "
        f"In steady state flowtwin's default drive for this set-up (roller #2's slip "
        f"parameters at {GREEFF_RF1000.drive.pinch_force_n:g} N, maximum feed force "
        f"{s190.max_force_n:.1f} N) needs {s190.force_n:.1f} N at 190 °C and 2 mm/s, with "
        f"{100 * s190.slip:.0f} % slip, and does not grind: the failure is not reproduced "
        "by the steady model (Greeff's slip also peaks ~5 s into an extrusion, Fig. 9, a "
        "transient the steady model leaves out). In the print-job test below the "
        "twin's dynamic model does grind at 190 °C and 2 mm/s: with the 0.3 mm layer's "
        "back-pressure under the nozzle the feed force exceeds the maximum.",
        *print_job_notes(ctx),
    ]


SECTION = PaperSection(PAPER, "Greeff, Schilling: Closed loop control of slippage during "
                              "filament transport in molten material extrusion. Additive "
                              "Manufacturing 14 (2017) 31–38", "003", CLAIMS, FIGURES, notes)
