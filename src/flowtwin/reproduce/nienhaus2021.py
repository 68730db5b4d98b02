"""[000] Nienhaus, Spiehl, Dörsam 2021: roller filament drives — claims and figures.

Values come from the roller data file (``flowtwin.profiles.load_rollers``), the drive laws
(:mod:`flowtwin.physics.drive`) and the virtual test stand (:mod:`flowtwin.teststand`,
campaigns in :mod:`flowtwin.reproduce.context`).
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from flowtwin.physics.drive import max_feed_force_n, min_pinch_force_n, slip_gradient
from flowtwin.reproduce.claims import (
    Claim,
    Outcome,
    RowKind,
    rounded,
    within_abs,
    within_rel,
)
from flowtwin.reproduce.context import STAND_K_P, ReproContext
from flowtwin.reproduce.figures import FigureSpec, PaperSection
from flowtwin.teststand import compare_with_roller
from flowtwin.teststand.figures import (
    new_figure,
    plot_max_force,
    plot_pinch_law,
    plot_r_squared_histogram,
    plot_slip_record,
    plot_velocity_law,
)

__all__ = ["SECTION"]

PAPER = "nienhaus2021"
#: The virtual test stand is built on the published laws (Table 3's Eqs. 6 and 8, the
#: max-force fits of Figs. 4-8): rows that recover them from its records check the test-stand
#: procedure, and carry these values rather than predict them.
_ANCHOR = RowKind.ANCHOR
_STAND = "flowtwin.teststand (virtual stand + fits)"
_TOOTHED = (1, 2, 3, 5, 6, 7)  # the plain roller #4 has no teeth [000 Table 2]
#: Eq. 9 agreement regarded as consistent: Table 3 rounds F_p,min to whole newtons and
#: k_inf to 0.01 %/N (1.5-2.5 % on the square root); docs/spec.md §3.1 states 2 % for rows != #3.
_FPMIN_REL = 0.02


def _fp_min_claim(number: int) -> Claim:
    def compute(ctx: ReproContext) -> Outcome:
        r = ctx.rollers[number]
        assert r.fp_min_tabulated_N is not None
        eq9 = float(min_pinch_force_n(r.k_s_pct_N, r.k_inf_pct_per_N))
        return within_rel(r.fp_min_tabulated_N, eq9, _FPMIN_REL,
                          why="Table 3 rounds F_p,min to 1 N and k_inf to 0.01 %/N",
                          note=f"Eq. 9 with k_s = {r.k_s_pct_N:g} %·N, "
                               f"k_inf = {r.k_inf_pct_per_N:g} %/N")
    return Claim(PAPER, f"table3-fpmin-{number}",
                 f"Table 3: F_p,min of roller #{number} is Eq. 9 of its k_s and k_inf",
                 "[000 Table 3, Eq. 9]", compute, unit="N", figure="fpmin",
                 engine="flowtwin.physics.drive.min_pinch_force_n")


def _fp_min_3_discrepancy(ctx: ReproContext) -> Outcome:
    r = ctx.rollers[3]
    eq9 = float(min_pinch_force_n(r.k_s_pct_N, r.k_inf_pct_per_N))
    tab = r.fp_min_tabulated_N or math.nan
    rel = (tab - eq9) / eq9
    return Outcome(tab, round(eq9, 2), "a data check: passes when Eq. 9 disagrees with the "
                   f"printed value by more than {100 * _FPMIN_REL:g} %", abs(rel) > _FPMIN_REL,
                   f"printed 77 N is {100 * rel:+.1f} % off Eq. 9 (docs/spec.md §3.1); the "
                   "other six rows agree within 2 %")


def _fp_min_3_explained(ctx: ReproContext) -> Outcome:
    r = ctx.rollers[3]
    tab = r.fp_min_tabulated_N or math.nan
    at_5pct = float(min_pinch_force_n(r.k_s_pct_N, r.k_inf_pct_per_N, tolerance=0.05))
    out = within_rel(tab, at_5pct, _FPMIN_REL, why="rounding of Table 3, as for the other rows")
    return Outcome(out.paper_value, out.flowtwin_value, out.tolerance, out.passed,
                   "Eq. 9 with a 5 % instead of 10 % criterion, sqrt(k_s/(0.05·k_inf)) — "
                   "equivalently k_s = 192 %·N (twice the printed 96.0) — gives the printed "
                   "77 N: the discrepancy is a factor 2 under the root; which number is the "
                   f"misprint the paper does not say. {out.note}")


def _fig9a(ctx: ReproContext) -> Outcome:
    camp = ctx.pinch_campaign(3)
    sel = [r for r in camp.analysis.results if r.key.pinch_force_set_n == 80.0
           and r.key.nominal_speed_mm_s == 1.0 and r.slip is not None]
    slopes = [100.0 * r.slip_gradient_per_n for r in sel]
    return within_abs(0.33, float(np.mean(slopes)), 0.01, unit="%/N",
                      why="the uncertainty of k_inf in Table 3; Fig. 9a prints two digits",
                      note=f"mean of {len(slopes)} virtual-stand records of roller #3 at 80 N, "
                           "1 mm/s (Eq. 6 law: 96/80² + 0.32 = 0.335 %/N)")


def _fig9b(ctx: ReproContext) -> Outcome:
    r2 = np.concatenate([ctx.pinch_campaign(n).analysis.r_squared for n in ctx.rollers])
    med = float(np.median(r2))
    return Outcome("good R² for all regressions", round(med, 4),
                   "median R² >= 0.9 ('good coefficients of determination')", med >= 0.9,
                   f"{r2.size} regressions of 7 rollers; 5th percentile "
                   f"{float(np.percentile(r2, 5)):.3f}: the spread comes from the encoder "
                   "noise, 5 % slip per sample at 0.5 mm/s")


def _max_force_claim(number: int) -> Claim:
    figure = {1: "4", 2: "5", 3: "6", 4: "7", 5: "8a", 6: "8b", 7: "8c"}[number]

    def compute(ctx: ReproContext) -> Outcome:
        camp = ctx.pinch_campaign(number)
        lo, hi = ctx.grinding_range_n(number)
        mf = camp.analysis.max_force
        fit = camp.roller.max_feed_force_fit
        assert fit is not None
        paper = [fit.c2_per_N, fit.c1, fit.c0_N]
        if mf is None:
            return Outcome(paper, None, "a fit", False,
                           camp.analysis.problems.get("max_force", "no fit"))
        grid = np.array(mf.pinch_forces_n)
        check = {c.name: c for c in compare_with_roller(
            camp.analysis, camp.roller, pinch_forces_n=grid.tolist())}["F_f,max curve"]
        dev = mf.max_feed_force_n(grid) - max_feed_force_n(grid, (fit.c0_N, fit.c1,
                                                                   fit.c2_per_N))
        worst = int(np.argmax(np.abs(dev)))
        note = (f"2nd-order fit of {mf.n_points} virtual-stand maxima at {lo:g}-{hi:g} N; "
                f"largest deviation {dev[worst]:+.2f} N at {grid[worst]:g} N")
        if hi < 150.0:
            note += (f"; above {hi:g} N Table 3's Eq. 6 reaches 90 % slip before this maximum "
                     "force, so those records stall by slip, not by failure")
        return Outcome(paper, rounded(mf.coeffs[::-1], 4),
                       "curve within 3 standard errors of the recovered fit + 0.5 N at every "
                       "tested pinch force", check.passed, note)
    return Claim(PAPER, f"fig{figure}-max-force-{number}",
                 f"Fig. {figure}: maximum feed force of roller #{number}, 2nd-order fit "
                 "(c2, c1, c0) recovered by the test-stand procedure",
                 f"[000 Fig. {figure[0]}]", compute, unit="N",
                 figure="maxforce", kind=_ANCHOR, engine=_STAND)


def _eq6_claim(number: int) -> Claim:
    def compute(ctx: ReproContext) -> Outcome:
        camp = ctx.pinch_campaign(number)
        checks = {c.name: c for c in compare_with_roller(camp.analysis, camp.roller)}
        ks, ki = checks["k_s"], checks["k_inf"]
        r = camp.roller
        n_fit = camp.analysis.pinch_law.n_points if camp.analysis.pinch_law else 0
        return Outcome([r.k_s_pct_N, r.k_inf_pct_per_N],
                       rounded([ks.recovered or math.nan, ki.recovered or math.nan], 4),
                       f"within Table 3's uncertainty (±{r.k_s_pct_N_err:g} %·N, "
                       f"±{r.k_inf_pct_per_N_err:g} %/N)", ks.passed and ki.passed,
                       f"Eq. 6 fitted to {n_fit} virtual-stand slip gradients (10-150 N, "
                       "0.5-15 mm/s, 3 repeats)")
    return Claim(PAPER, f"table3-eq6-{number}",
                 f"Table 3: k_s, k_inf of roller #{number} recovered from test-stand records",
                 "[000 Table 3, Eq. 6, Fig. 10]", compute, unit="%·N, %/N",
                 figure="pinch-law" if number == 3 else None, kind=_ANCHOR, engine=_STAND)


def _eq8_claim(number: int) -> Claim:
    def compute(ctx: ReproContext) -> Outcome:
        camp = ctx.velocity_campaign(number)
        checks = {c.name: c for c in compare_with_roller(camp.analysis, camp.roller)}
        r = camp.roller
        vl = camp.analysis.velocity_law
        names: tuple[str, ...]
        if r.velocity_dependent:
            names = ("a", "b", "c")
            paper: list[float] = [r.a_pct_per_N or math.nan, r.b_pct_per_N or math.nan,
                                  r.c_s_per_mm or math.nan]
            tol = (f"within Table 3's uncertainty (±{r.a_pct_per_N_err:g}, "
                   f"±{r.b_pct_per_N_err:g} %/N, ±{r.c_s_per_mm_err:g} s/mm)")
        else:
            names = ("a", "velocity law")
            paper = [r.a_pct_per_N or math.nan]
            tol = (f"a within ±{r.a_pct_per_N_err:g} %/N and no significant velocity term "
                   "(Table 3: b·exp(-c·v) -> 0)")
        got = rounded([checks[n].recovered or math.nan for n in ("a", "b", "c")
                       if n in names], 4)
        passed = all(checks[n].passed for n in names)
        return Outcome(paper, got, tol, passed,
                       f"Eq. 8 fitted to the per-speed means of {vl.n_points if vl else 0} "
                       f"virtual-stand records at 80-130 N; {vl.reason if vl else ''}")
    return Claim(PAPER, f"table3-eq8-{number}",
                 f"Table 3: a, b, c of roller #{number} recovered from test-stand records "
                 "at 80-130 N", "[000 Table 3, Eq. 8, Fig. 11]", compute,
                 unit="%/N, %/N, s/mm",
                 figure="velocity-law" if number in (3, 7) else None, kind=_ANCHOR,
                 engine=_STAND)


def _fig10_shape(ctx: ReproContext) -> Outcome:
    pl = ctx.pinch_campaign(3).analysis.pinch_law
    assert pl is not None
    excess = float(pl.gradient_per_n(60.0) / pl.k_inf_per_n - 1.0)
    decline = float(pl.gradient_per_n(10.0) / pl.gradient_per_n(60.0))
    return Outcome("within 10 % of k_inf above 60 N", round(100 * excess, 2),
                   "< 10 % (the criterion of Eq. 9)", excess < 0.1,
                   f"recovered s'(60 N) is {100 * excess:.1f} % above k_inf; s' falls by a "
                   f"factor {decline:.2f} from 10 N to 60 N ('decline from 10 N to 60 N and a "
                   "nearly constant region above')")


def _fig11a(ctx: ReproContext) -> Outcome:
    vl = ctx.velocity_campaign(3).analysis.velocity_law
    assert vl is not None
    ratio = float(vl.gradient_per_n(0.5) / vl.gradient_per_n(15.0))
    r = ctx.rollers[3]
    assert r.a_pct_per_N is not None and r.b_pct_per_N is not None and r.c_s_per_mm is not None
    paper = (r.a_pct_per_N + r.b_pct_per_N * math.exp(-0.5 * r.c_s_per_mm)) / (
        r.a_pct_per_N + r.b_pct_per_N * math.exp(-15.0 * r.c_s_per_mm))
    out = within_rel(paper, ratio, 0.05, why="Table 3's b is ±33 %; 5 % keeps the shape")
    return Outcome(round(paper, 4), out.flowtwin_value, out.tolerance,
                   out.passed and vl.velocity_dependent,
                   f"s'(0.5 mm/s)/s'(15 mm/s), declining with speed; exponential term "
                   f"significant: {vl.velocity_dependent} ({vl.reason}); {out.note}")


def _fig11b(ctx: ReproContext) -> Outcome:
    vl = ctx.velocity_campaign(7).analysis.velocity_law
    assert vl is not None
    return Outcome("no significant velocity dependence", vl.reason,
                   "the F-test rejects the exponential term (p >= 0.01) or it is not "
                   "identifiable", not vl.velocity_dependent,
                   f"s' = a = {100 * vl.a_per_n:.4f} %/N")


def _slip_30(ctx: ReproContext) -> Outcome:
    values = []
    fp = np.arange(80.0, 151.0, 10.0)
    for n in _TOOTHED:
        r = ctx.rollers[n]
        fit = r.max_feed_force_fit
        assert fit is not None
        fmax = max_feed_force_n(fp, (fit.c0_N, fit.c1, fit.c2_per_N))
        values.append(STAND_K_P + slip_gradient(fp, r.k_s_n, r.k_inf_per_n) * fmax)
    s = 100.0 * np.concatenate(values)
    med = float(np.median(s))
    return Outcome(30.0, round(med, 1), "±10 percentage points ('~30 %', one significant "
                   "digit)", abs(med - 30.0) <= 10.0,
                   f"slip at the maximum feed force, Eq. 6 × Figs. 4–8 trend, toothed rollers "
                   f"at 80–150 N: median {med:.1f} %, range {s.min():.0f}–{s.max():.0f} %")


CLAIMS: tuple[Claim, ...] = (
    *(_fp_min_claim(n) for n in (1, 2, 4, 5, 6, 7)),
    Claim(PAPER, "table3-fpmin-3-discrepancy",
          "Table 3: roller #3's F_p,min = 77 N does not follow from Eq. 9 with its own k_s, "
          "k_inf (54.8 N)", "[000 Table 3, Eq. 9]", _fp_min_3_discrepancy, unit="N",
          figure="fpmin", kind=RowKind.DATA_CHECK, engine="flowtwin.physics.drive"),
    Claim(PAPER, "table3-fpmin-3-explained",
          "Table 3: roller #3's 77 N is Eq. 9 with a factor 2 under the root (5 % criterion)",
          "[000 Table 3, Eq. 9]", _fp_min_3_explained, unit="N", figure="fpmin",
          kind=RowKind.DATA_CHECK, engine="flowtwin.physics.drive"),
    Claim(PAPER, "fig9a-slip-gradient",
          "Fig. 9a: s' = 0.33 %/N for roller #3 at 80 N and 1 mm/s", "[000 Fig. 9a]", _fig9a,
          unit="%/N", figure="fig9", engine=_STAND),
    Claim(PAPER, "fig9b-r-squared", "Fig. 9b: the linear slip regressions fit well",
          "[000 Fig. 9b]", _fig9b, figure="fig9", engine=_STAND),
    *(_max_force_claim(n) for n in range(1, 8)),
    *(_eq6_claim(n) for n in range(1, 8)),
    *(_eq8_claim(n) for n in range(1, 8)),
    Claim(PAPER, "fig10-shape", "Fig. 10: roller #3's s' declines from 10 to 60 N and is "
          "nearly constant above", "[000 Fig. 10, §4.2]", _fig10_shape, unit="%",
          figure="pinch-law", engine=_STAND),
    Claim(PAPER, "fig11a-decline", "Fig. 11a: roller #3's s' declines with feed velocity",
          "[000 Fig. 11a]", _fig11a, figure="velocity-law", engine=_STAND),
    Claim(PAPER, "fig11b-flat", "Fig. 11b: roller #7's s' has no significant velocity "
          "dependence", "[000 Fig. 11b]", _fig11b, figure="velocity-law", engine=_STAND),
    Claim(PAPER, "slip-30-percent", "Slip can reach ~30 % just before the drive fails",
          "[000 §5]", _slip_30, unit="%", figure="maxforce",
          engine="flowtwin.physics.drive (Eq. 6 × Figs. 4–8)"),
)


# ---------------------------------------------------------------- figures

def _fig_fpmin(ctx: ReproContext) -> Figure:
    fig, (ax,) = new_figure(6.4, 3.8)
    numbers = sorted(ctx.rollers)
    tab = [ctx.rollers[n].fp_min_tabulated_N or math.nan for n in numbers]
    eq9 = [float(min_pinch_force_n(ctx.rollers[n].k_s_pct_N, ctx.rollers[n].k_inf_pct_per_N))
           for n in numbers]
    x = np.arange(len(numbers))
    ax.bar(x - 0.2, tab, 0.4, label="Table 3 (printed)", color="tab:blue")
    ax.bar(x + 0.2, eq9, 0.4, label="Eq. 9 of Table 3's k_s, k_inf", color="tab:orange")
    ax.set_xticks(x, [f"#{n}" for n in numbers])
    ax.set_ylabel("minimal pinch force $F_{p,min}$ (N)")
    i3 = numbers.index(3)
    ax.annotate(f"{tab[i3]:g} N printed,\n{eq9[i3]:.1f} N by Eq. 9", (i3, tab[i3]),
                (i3 + 0.6, 150), arrowprops={"arrowstyle": "->"}, fontsize=8)
    ax.legend(fontsize=8)
    return fig


def _fig9(ctx: ReproContext) -> Figure:
    camp = ctx.pinch_campaign(3)
    fig, (a, b) = new_figure(11.0, 4.0, cols=2)
    pairs = [(rec, res) for rec, res in zip(camp.records, camp.analysis.results, strict=True)
             if rec.key.pinch_force_set_n == 80.0 and rec.key.nominal_speed_mm_s == 1.0
             and res.slip is not None]
    plot_slip_record(a, *pairs[0])
    a.set_title("(a) roller #3, 80 N, 1 mm/s (virtual stand)")
    results = [res for n in ctx.rollers for res in ctx.pinch_campaign(n).analysis.results]
    plot_r_squared_histogram(b, results)
    b.set_title(f"(b) R² of all regressions, 7 rollers ({b.get_title()})", fontsize=9)
    return fig


def _fig_maxforce(ctx: ReproContext) -> Figure:
    fig, axes = new_figure(13.0, 9.0, rows=3, cols=3)
    for ax, n in zip(axes, range(1, 8), strict=False):
        camp = ctx.pinch_campaign(n)
        hi = ctx.grinding_range_n(n)[1]
        plot_max_force(ax, camp.analysis.results, camp.analysis.max_force, roller=camp.roller)
        if hi < 150.0:
            ax.axvspan(hi + 5.0, 155.0, color="0.9", zorder=0)
        ax.set_title(f"roller #{n}", fontsize=10)
        ax.legend(fontsize=6)
    ax = axes[7]
    fp = np.linspace(10.0, 150.0, 100)
    for n in range(1, 8):
        fit = ctx.rollers[n].max_feed_force_fit
        assert fit is not None
        ax.plot(fp, max_feed_force_n(fp, (fit.c0_N, fit.c1, fit.c2_per_N)), label=f"#{n}")
    ax.set_title("published trends (Fig. 8d style)", fontsize=10)
    ax.set_xlabel("pinch force $F_p$ (N)")
    ax.legend(fontsize=6, ncols=2)
    ax = axes[8]
    for n in _TOOTHED:
        r = ctx.rollers[n]
        fit = r.max_feed_force_fit
        assert fit is not None
        fmax = max_feed_force_n(fp, (fit.c0_N, fit.c1, fit.c2_per_N))
        ax.plot(fp, 100 * (STAND_K_P + slip_gradient(fp, r.k_s_n, r.k_inf_per_n) * fmax),
                label=f"#{n}")
    ax.axhline(30.0, color="black", ls=":", lw=1)
    ax.set_title("slip at the maximum feed force (Eq. 6)", fontsize=10)
    ax.set_xlabel("pinch force $F_p$ (N)")
    ax.set_ylabel("slip (%)")
    ax.legend(fontsize=6, ncols=2)
    return fig


def _fig_pinch(ctx: ReproContext) -> Figure:
    camp = ctx.pinch_campaign(3)
    fig, (ax,) = new_figure(6.4, 4.2)
    plot_pinch_law(ax, camp.analysis.results, camp.analysis.pinch_law, roller=camp.roller)
    ax.set_title("roller #3: slip gradient over pinch force (Fig. 10 style)")
    ax.set_ylim(0.2, 1.6)
    return fig


def _fig_velocity(ctx: ReproContext) -> Figure:
    fig, (a, b) = new_figure(11.0, 4.0, cols=2)
    for ax, n, tag in ((a, 3, "(a) roller #3"), (b, 7, "(b) roller #7")):
        camp = ctx.velocity_campaign(n)
        plot_velocity_law(ax, camp.analysis.results, camp.analysis.velocity_law,
                          roller=camp.roller)
        ax.set_title(f"{tag}, 80-130 N (Fig. 11 style)", fontsize=10)
    return fig


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("fpmin", "[000 Table 3] F_p,min as printed and by Eq. 9: roller #3 is the odd "
                        "one out.", _fig_fpmin),
    FigureSpec("fig9", "[000 Fig. 9] (a) slip against feed force of one virtual-stand record "
                       "of roller #3 at 80 N, 1 mm/s, with its regression; (b) R² of all "
                       "regressions.", _fig9),
    FigureSpec("maxforce", "[000 Figs. 4–8] per-record maximum feed force of the virtual "
                           "stand (marker area ~ speed), the recovered 2nd-order fit (black) "
                           "and the published fit (dashed); grey: records that stall by "
                           "complete slip. Last panel: slip at the maximum feed force.",
               _fig_maxforce),
    FigureSpec("pinch-law", "[000 Fig. 10] slip gradient of roller #3 over the pinch force "
                            "(virtual stand) with the recovered and the published Eq. 6.",
               _fig_pinch),
    FigureSpec("velocity-law", "[000 Fig. 11] slip gradient at 80–130 N over the feed "
                               "velocity for rollers #3 and #7 (virtual stand), recovered and "
                               "published Eq. 8.", _fig_velocity),
)


def notes(ctx: ReproContext) -> list[str]:
    """Findings beyond the rows: the consistency of Table 3's two slip laws."""
    fp = np.array([80.0, 90.0, 100.0, 110.0, 120.0, 130.0])
    v = np.array([0.5, 1.0, 2.0, 5.0, 10.0, 15.0])
    lines = ["**Table 3's two slip laws describe the same 80–130 N data differently.** The "
             "mean slip gradient over 80–130 N × 0.5–15 mm/s from Eq. 6 (k_s, k_inf) and from "
             "Eq. 8 (a, b, c), computed from the roller data file:", "",
             "| roller | Eq. 6 mean s' (%/N) | Eq. 8 mean s' (%/N) | difference | "
             "Table 3 ± of a |", "|---|---|---|---|---|"]
    for n in sorted(ctx.rollers):
        r = ctx.rollers[n]
        eq6 = float(np.mean(slip_gradient(fp, r.k_s_pct_N, r.k_inf_pct_per_N)))
        g = np.full_like(v, r.a_pct_per_N or math.nan)
        if r.velocity_dependent and r.b_pct_per_N is not None and r.c_s_per_mm is not None:
            g = g + r.b_pct_per_N * np.exp(-r.c_s_per_mm * v)
        eq8 = float(np.mean(g))
        lines.append(f"| #{n} | {eq6:.3f} | {eq8:.3f} | {eq6 - eq8:+.3f} | "
                     f"{r.a_pct_per_N_err:g} |")
    lines += ["", "Where the difference exceeds the uncertainty of a (rollers #2, #3, #4, #6), "
              "no single s'(F_p, v) satisfies both rows, so the virtual stand is run once with "
              "each law (docs/teststand.md). Eq. 6 at 80 N and 1 mm/s gives 0.335 %/N — Fig. "
              "9a's 0.33 %/N — while Eq. 8 at 1 mm/s gives "
              f"{0.24 + 0.18 * math.exp(-0.32):.3f} %/N for roller #3."]
    return lines


SECTION = PaperSection(PAPER, "Nienhaus, Spiehl, Dörsam: Investigations on Roller-Based "
                              "Filament Drives. J. Manuf. Mater. Process. 2021, 5, 53",
                       "000", CLAIMS, FIGURES, notes)
