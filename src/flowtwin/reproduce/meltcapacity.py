"""Melt capacity of hot ends against public maximum-flow figures (docs/spec.md §3.9).

Not a seed paper: published measurements of hot-end makers and testers, split into a fit
set (one figure: the E3D V6, which fixes ``MELT_LENGTH_FACTOR``) and a check set (every
other figure; never used to tune anything). The model quantity is the hot end's *melt
capacity* (:mod:`flowtwin.physics.melt_capacity`: the flow where the melt zone alone
doubles the nozzle pressure) with PLA 4043D at the figure's temperature; published
figures are taken with drives strong enough that the hot end gives out. Each row says in
its text whether it is the **anchor** (fitted) or a **check**.

Sources (as accessible to the project, see docs/physics.md §9):

* ELLIS — Ellis' Print Tuning Guide, "Determining Maximum Volumetric Flow Rate",
  "Approximate Values" for a standard 0.4 mm brass nozzle (ellis3dp.com): V6 11, Revo 11,
  Dragon SF 15, Dragon HF 24, Rapido HF 24, Rapido UHF 30, Mosquito 20, Mosquito Magnum
  30 mm³/s.
* OLIVER — S. J. Oliver, "Extrudable Me! Exploring Extrusion Variability and Limits" (2013),
  as cited by [003 §1 ref. 7]: "an extrusion rate limit for a 0.4 mm nozzle diameter and
  white PLA of around 8–10 mm³/s".
* DUET — Duet3D guide "maximum flow rate" (duet3d.dozuki.com), Ender 3 Pro stock hot end
  and extruder, PLA at 220 °C: 5 mm/s of 1.67 mm filament (10.9 mm³/s) held, 6 mm/s
  (13.1 mm³/s) skipped.
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass

from matplotlib.figure import Figure

from flowtwin.physics import defaults
from flowtwin.profiles import HotendProfile, MaterialProfile, load_builtin
from flowtwin.reproduce.claims import Claim, Outcome, RowKind, rounded, within_rel
from flowtwin.reproduce.context import ReproContext
from flowtwin.reproduce.figures import FigureSpec, PaperSection
from flowtwin.teststand.figures import new_figure

__all__ = ["CHECK_SET", "FIT_SET", "SECTION", "PublishedFlow", "predicted_capacity_mm3_s"]

PAPER = "meltcapacity"
_ENGINE = "flowtwin.physics.melt_capacity.melt_capacity_mm3_s"
_ELLIS = "[public: Ellis' Print Tuning Guide, max volumetric flow, approximate values]"


@dataclass(frozen=True)
class PublishedFlow:
    """One published maximum flow: hot end profile, value (mm³/s), temperature, source."""

    hotend: str
    label: str
    published_mm3_s: float
    temperature_c: float
    source: str


FIT_SET = (PublishedFlow("e3d-v6-0.4", "E3D V6", 11.0, 215.0, _ELLIS),)
#: The high-flow designs of ELLIS (checks of the nozzle-family heated lengths).
HIGH_FLOW = (
    PublishedFlow("phaetus-dragon-sf-0.4", "Dragon SF", 15.0, 215.0, _ELLIS),
    PublishedFlow("phaetus-dragon-hf-0.4", "Dragon HF", 24.0, 215.0, _ELLIS),
    PublishedFlow("phaetus-rapido-hf-0.4", "Rapido HF", 24.0, 215.0, _ELLIS),
    PublishedFlow("phaetus-rapido-uhf-0.4", "Rapido UHF", 30.0, 215.0, _ELLIS),
    PublishedFlow("slice-mosquito-0.4", "Mosquito", 20.0, 215.0, _ELLIS),
    PublishedFlow("slice-mosquito-magnum-0.4", "Mosquito Magnum", 30.0, 215.0, _ELLIS),
)
CHECK_SET = (
    PublishedFlow("e3d-revo-six-0.4", "E3D Revo Six", 11.0, 215.0, _ELLIS),
    PublishedFlow("e3d-v6-0.4", "0.4 mm hot end, white PLA (Oliver 2013)", 9.0, 215.0,
            "[003 §1, ref. 7] (Oliver 2013): 8–10 mm³/s"),
    PublishedFlow("creality-mk8-0.4", "Creality MK8 (Ender 3 Pro)", 12.0, 220.0,
            "[public: Duet3D max flow rate guide, Ender 3 Pro, 220 °C]: held 10.9, skipped "
            "13.1 mm³/s"),
    *HIGH_FLOW,
)


def predicted_capacity_mm3_s(hotend: str, temperature_c: float) -> float:
    """Melt capacity of a built-in hot end with PLA 4043D at ``temperature_c``, mm³/s."""
    from flowtwin.physics.melt_capacity import melt_capacity_mm3_s
    from flowtwin.simulation.viscosity import viscosity_pa_s

    hot = load_builtin(hotend, "hotend")
    mat = load_builtin("pla-4043d", "material")
    assert isinstance(hot, HotendProfile) and isinstance(mat, MaterialProfile)
    length = hot.effective_heated_length_mm(defaults.MELT_LENGTH_FACTOR)
    alpha = mat.diffusivity_mm2_s
    assert length is not None and alpha is not None
    return melt_capacity_mm3_s(lambda t: float(viscosity_pa_s(mat, t)), set_c=temperature_c,
                               inlet_c=hot.melt_inlet_temperature_c, diffusivity_mm2_s=alpha,
                               heated_length_mm=length)


def _anchor(ctx: ReproContext) -> Outcome:
    f = FIT_SET[0]
    q = predicted_capacity_mm3_s(f.hotend, f.temperature_c)
    return within_rel(f.published_mm3_s, q, 0.005,
                      why="ANCHOR: MELT_LENGTH_FACTOR is fitted to this figure, not a "
                          "reproduction", note="fit set (1 figure)")


def _check(fig: PublishedFlow, rel: float, why: str, note: str = "") -> Claim:
    def compute(ctx: ReproContext) -> Outcome:
        q = predicted_capacity_mm3_s(fig.hotend, fig.temperature_c)
        return within_rel(fig.published_mm3_s, q, rel, why=why, note=note)
    return Claim(PAPER, f"check-{fig.hotend}-{int(fig.published_mm3_s)}",
                 f"melt capacity of {fig.label} at {fig.temperature_c:g} °C",
                 fig.source, compute, unit="mm³/s", figure="capacity", engine=_ENGINE)


def _high_flow(ctx: ReproContext) -> Outcome:
    pub = [f.published_mm3_s for f in HIGH_FLOW]
    pred = [predicted_capacity_mm3_s(f.hotend, f.temperature_c) for f in HIGH_FLOW]
    err = [100.0 * (p - q) / q for p, q in zip(pred, pub, strict=True)]
    worst = min(err)
    ok = all(p <= 1.1 * q for p, q in zip(pred, pub, strict=True))
    return Outcome(
        rounded(pub, 3), rounded(pred, 3),
        "conservative: no prediction above the published figure + 10 % (the twin must not "
        "promise flow a hot end lacks); NOT a prediction within a tolerance", ok,
        f"errors {', '.join(f'{e:+.0f} %' for e in err)}; median {statistics.median(err):+.0f} "
        f"%, worst {worst:+.0f} %: with heated lengths from the nozzle family alone (V6 "
        "block 11.5 mm, Volcano block 20 mm) the model under-predicts the high-flow "
        "designs, whose heaters reach further along the melt path than the block height "
        "(their melt-zone lengths are not published in a source found here)")


CLAIMS: tuple[Claim, ...] = (
    Claim(PAPER, "anchor-e3d-v6-11", "melt capacity of the E3D V6 0.4 at 215 °C "
          "(fit set: fixes MELT_LENGTH_FACTOR)", _ELLIS, _anchor, unit="mm³/s",
          figure="capacity", kind=RowKind.ANCHOR, engine=_ENGINE),
    _check(CHECK_SET[0], 0.15, "±15 %: the figure is rounded to 1 mm³/s and 'approximate'",
           note="Revo Six heated length PROVISIONAL (taken as the V6's): a weak check"),
    _check(CHECK_SET[1], 0.30, "±30 %: 8–10 mm³/s is a practical limit of an unnamed 2013 "
           "hot end, compared with the V6's capacity"),
    _check(CHECK_SET[2], 0.30, "±30 %: the figure is the middle of the bracket 10.9–13.1 "
           "mm³/s (held / skipped) with the stock extruder, not the reference drive"),
    Claim(PAPER, "check-high-flow-designs",
          "high-flow designs (Dragon SF/HF, Rapido HF/UHF, Mosquito, Magnum): the model "
          "never promises more flow than published (it under-predicts them: see the note)",
          _ELLIS, _high_flow, unit="mm³/s",
          figure="capacity", engine=_ENGINE),
)


def _fig_capacity(ctx: ReproContext) -> Figure:
    fig, (ax,) = new_figure(6.4, 4.2)
    figs = (*FIT_SET, *CHECK_SET)
    pub = [f.published_mm3_s for f in figs]
    pred = [predicted_capacity_mm3_s(f.hotend, f.temperature_c) for f in figs]
    for i, (f, p, q) in enumerate(zip(figs, pub, pred, strict=True)):
        ax.plot(p, q, "s" if i == 0 else "o", color="C3" if i == 0 else "C0")
        ax.annotate(f.label.split(" (")[0], (p, q), fontsize=6, xytext=(3, 2),
                    textcoords="offset points")
    top = 1.1 * max(*pub, *pred)
    ax.plot([0, top], [0, top], "k:", lw=1)
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_xlabel("published maximum flow (mm³/s)")
    ax.set_ylabel("model melt capacity (mm³/s)")
    ax.set_title("Melt capacity, PLA: fit (square) and checks (circles)")
    return fig


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("capacity", "[public] hot-end melt capacity against published maximum flows "
                           "(fit: E3D V6; all others are checks).", _fig_capacity),
)


def notes(ctx: ReproContext) -> list[str]:
    """What the rows do not say."""
    return [
        "The melt capacity is the flow where the melt zone alone doubles the nozzle's "
        "pressure (docs/physics.md §9). The machine's maximum volumetric flow "
        "(`flowtwin limits`) adds the drive: for `tronvoll2019` (roller #3 at 80 N) it is "
        "12.2 mm³/s in free extrusion at 215 °C, bound by slip (5 % at 18 N).",
        "Hot ends without a published melt-zone length carry PROVISIONAL heated lengths "
        "(nozzle-family rule); their checks test that rule as much as the heat-transfer "
        "model. Nextruder and Bambu X1/P1 have profiles but no public figure was found: "
        "they are not validated.",
    ]


SECTION = PaperSection(PAPER, "Public maximum-flow figures of hot ends (makers' and testers'); "
                              "not a seed", "public", CLAIMS, FIGURES, notes)
