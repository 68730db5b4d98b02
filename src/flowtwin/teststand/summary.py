"""JSON-able summaries and figure sets of a test-stand evaluation (used by the CLI).

:func:`analyse_file` reads a schema-1 CSV file, evaluates every roller in it
(:func:`~flowtwin.teststand.report.analyse_campaign`), compares rollers ``"1"`` … ``"7"``
with [000 Table 3] and optionally writes the figures of [000 Figs. 4–11] per roller.
Numbers are reported in the paper's units (% for slip, %·N, %/N, s/mm, N).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from flowtwin.profiles import Roller, load_rollers
from flowtwin.teststand.analysis import analyse_records
from flowtwin.teststand.figures import (
    new_figure,
    plot_max_force,
    plot_pinch_law,
    plot_r_squared_histogram,
    plot_slip_record,
    plot_velocity_law,
    save_figure,
)
from flowtwin.teststand.fits import r_squared_histogram
from flowtwin.teststand.records import Record, read_records_csv
from flowtwin.teststand.report import CampaignAnalysis, analyse_campaign, compare_with_roller

__all__ = ["analyse_file", "campaign_summary", "write_campaign_figures"]


def _num(x: float | None, digits: int = 6) -> float | None:
    if x is None or not math.isfinite(x):
        return None
    return float(f"{x:.{digits}g}")


def campaign_summary(analysis: CampaignAnalysis, *,
                     roller: Roller | None = None) -> dict[str, Any]:
    """The evaluation of one roller as a JSON-able dict (paper units).

    Parameters
    ----------
    analysis
        The campaign evaluation.
    roller
        Published parameters to compare with (``None``: no comparison).

    Returns
    -------
    dict
        ``roller_id``, ``records``, ``rejected`` (count and first reasons), ``r_squared``
        (median, minimum, histogram), ``pinch_law``, ``velocity_law``, ``max_force``,
        ``problems`` and, with a roller, ``comparison``.
    """
    r2 = analysis.r_squared
    counts, edges = r_squared_histogram(analysis.results, bins=10)
    out: dict[str, Any] = {
        "roller_id": analysis.roller_id,
        "records": len(analysis.results),
        "rejected": {"count": len(analysis.rejected),
                     "reasons": sorted({r.slip_problem or "" for r in analysis.rejected})[:5]},
        "r_squared": {"median": _num(float(np.median(r2))) if r2.size else None,
                      "min": _num(float(r2.min())) if r2.size else None,
                      "histogram": {"edges": [_num(e) for e in edges.tolist()],
                                    "counts": counts.tolist()}},
        "problems": dict(analysis.problems),
    }
    pl = analysis.pinch_law
    out["pinch_law"] = None if pl is None else {
        "k_s_pct_N": _num(100 * pl.k_s_n), "k_s_err_pct_N": _num(100 * pl.k_s_err_n),
        "k_inf_pct_per_N": _num(100 * pl.k_inf_per_n),
        "k_inf_err_pct_per_N": _num(100 * pl.k_inf_err_per_n),
        "fp_min_N": _num(pl.fp_min_n), "fp_min_err_N": _num(pl.fp_min_err_n),
        "pinch_forces_N": list(pl.pinch_forces_n), "records": pl.n_points}
    vl = analysis.velocity_law
    out["velocity_law"] = None if vl is None else {
        "velocity_dependent": vl.velocity_dependent, "reason": vl.reason,
        "a_pct_per_N": _num(100 * vl.a_per_n), "a_err_pct_per_N": _num(100 * vl.a_err_per_n),
        "b_pct_per_N": None if vl.b_per_n is None else _num(100 * vl.b_per_n),
        "b_err_pct_per_N": None if vl.b_err_per_n is None else _num(100 * vl.b_err_per_n),
        "c_s_per_mm": _num(vl.c_s_per_mm), "c_err_s_per_mm": _num(vl.c_err_s_per_mm),
        "p_value": _num(vl.p_value), "pinch_range_N": list(vl.pinch_range_n),
        "speeds_mm_s": list(vl.speeds_mm_s), "records": vl.n_points}
    mf = analysis.max_force
    out["max_force"] = None if mf is None else {
        "c0_N": _num(mf.coeffs[0]), "c1": _num(mf.coeffs[1]), "c2_per_N": _num(mf.coeffs[2]),
        "errors": [_num(e) for e in mf.errors], "rms_residual_N": _num(mf.rms_residual_n),
        "records": mf.n_points}
    if roller is not None:
        out["comparison"] = [
            {"parameter": c.name, "unit": c.unit, "published": _num(c.published),
             "tolerance": _num(c.tolerance), "recovered": _num(c.recovered),
             "recovered_err": _num(c.recovered_err), "deviation": _num(c.deviation),
             "pass": c.passed, "note": c.note}
            for c in compare_with_roller(analysis, roller)]
    return out


def write_campaign_figures(analysis: CampaignAnalysis, records: Sequence[Record],
                           out_dir: str | os.PathLike[str], *,
                           roller: Roller | None = None) -> list[Path]:
    """Write the figures of [000 Figs. 4–11] for one roller as PNG files.

    Parameters
    ----------
    analysis
        The campaign evaluation.
    records
        The records it came from (for the sample record of Fig. 9a).
    out_dir
        Folder to write into (created if missing).
    roller
        Published parameters to overlay (``None``: recovered curves only).

    Returns
    -------
    list of Path
        ``roller-<id>-maxforce.png``, ``-slip-record.png``, ``-r2.png``, ``-pinch-law.png``,
        ``-velocity-law.png`` (those that could be drawn).
    """
    out = Path(out_dir)
    rid = analysis.roller_id
    paths: list[Path] = []
    fig, (ax,) = new_figure()
    plot_max_force(ax, analysis.results, analysis.max_force, roller=roller)
    ax.set_title(f"roller {rid}: maximum feed force")
    paths.append(save_figure(fig, out / f"roller-{rid}-maxforce.png"))
    with_slip = [(rec, res) for rec, res in zip(records, analysis.results, strict=True)
                 if res.slip is not None]
    if with_slip:
        target = (80.0, 1.0)  # the set point of [000 Fig. 9a]
        rec, res = min(with_slip, key=lambda p: (abs(p[0].key.pinch_force_set_n - target[0]),
                                                 abs(p[0].key.nominal_speed_mm_s - target[1])))
        fig, (ax,) = new_figure()
        plot_slip_record(ax, rec, res)
        paths.append(save_figure(fig, out / f"roller-{rid}-slip-record.png"))
        fig, (ax,) = new_figure()
        plot_r_squared_histogram(ax, analysis.results)
        paths.append(save_figure(fig, out / f"roller-{rid}-r2.png"))
        fig, (ax,) = new_figure()
        plot_pinch_law(ax, analysis.results, analysis.pinch_law, roller=roller)
        ax.set_title(f"roller {rid}: slip gradient over pinch force")
        paths.append(save_figure(fig, out / f"roller-{rid}-pinch-law.png"))
        if analysis.velocity_law is not None:
            fig, (ax,) = new_figure()
            plot_velocity_law(ax, analysis.results, analysis.velocity_law, roller=roller,
                              pinch_range_n=analysis.velocity_law.pinch_range_n)
            paths.append(save_figure(fig, out / f"roller-{rid}-velocity-law.png"))
    return paths


def analyse_file(path: str | os.PathLike[str], *,
                 figures_dir: str | os.PathLike[str] | None = None,
                 rollers: Mapping[int, Roller] | None = None,
                 compare: bool = True) -> dict[str, Any]:
    """Evaluate every roller in a test-stand CSV file.

    Parameters
    ----------
    path
        Schema-1 CSV file (:mod:`flowtwin.teststand.records`).
    figures_dir
        If given, write each roller's figures there.
    rollers
        Published rollers to compare with (default: [000]'s seven); a roller id ``"3"``
        is compared with roller 3.
    compare
        Compare with the published rollers where the id matches.

    Returns
    -------
    dict
        ``file``, ``records``, ``rollers`` (one :func:`campaign_summary` per roller id) and
        ``figures`` (paths written).

    Raises
    ------
    DataError
        If the file cannot be read or is malformed.
    """
    records = read_records_csv(path)
    catalogue = rollers if rollers is not None else (load_rollers() if compare else {})
    by_roller: dict[str, list[Record]] = {}
    for rec in records:
        by_roller.setdefault(rec.key.roller_id, []).append(rec)
    summaries: list[dict[str, Any]] = []
    figures: list[str] = []
    for rid in sorted(by_roller):
        recs = by_roller[rid]
        analysis = analyse_campaign(analyse_records(recs))
        roller = catalogue.get(int(rid)) if compare and rid.isdigit() else None
        summaries.append(campaign_summary(analysis, roller=roller))
        if figures_dir is not None:
            figures += [str(p) for p in write_campaign_figures(analysis, recs, figures_dir,
                                                               roller=roller)]
    return {"file": os.fspath(path), "records": len(records), "rollers": summaries,
            "figures": figures}
