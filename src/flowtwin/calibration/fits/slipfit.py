"""The drive's slip law from test-stand records, as a drive-profile fragment [000].

The evaluation itself belongs to :mod:`flowtwin.teststand` (per-record regression of slip
on feed force, the Eq. 6 fit over the pinch force, the Eq. 8 fit over the feed velocity at
80–130 N, the maximum-force fit [000 §4]); this module only runs it on a records file
(schema 1, docs/teststand.md) for one roller and turns the result into what a drive
profile takes:

* ``k_p_pct`` — the slip offset of [000 Eq. 6]: the mean intercept of the records'
  regressions (1σ: their standard deviation over √n), the number [000 Fig. 9a] reads as
  0.63 % for roller #3 at 80 N;
* ``[slip_overrides]`` — ``k_s_pct_N``, ``k_inf_pct_per_N`` [000 Eq. 6] and, when the
  exponential term is significant, ``a_pct_per_N``, ``b_pct_per_N``, ``c_s_per_mm``
  [000 Eq. 8], in the paper's units (the profile's), each with its 1σ error as a comment;
* the maximum-force fit ``F = c0 + c1·F_p + c2·F_p²`` [000 Figs. 4–8] as a comment (a
  drive profile has no key for it; a ``[custom_roller]`` does).

The fragment is checked against the drive profile's schema (``SlipOverrides``) before it
is written: a fit that gives a negative ``k_s``, say, is an error with its reason, not a
profile the loader would reject later.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import ValidationError

from flowtwin.calibration.fragment import format_toml_value, render_fragment
from flowtwin.errors import CalibrationError, DataError
from flowtwin.profiles.drive import SlipOverrides
from flowtwin.teststand.analysis import analyse_records
from flowtwin.teststand.records import read_records_csv
from flowtwin.teststand.report import CampaignAnalysis, analyse_campaign

__all__ = ["SlipCalibration", "fit_slip_records", "slip_calibration"]


@dataclass(frozen=True)
class SlipCalibration:
    """A drive's slip law fitted to its test-stand records.

    Attributes
    ----------
    source
        Records file.
    analysis
        The test stand's evaluation of the roller's records.
    k_p_pct, k_p_err_pct
        Slip offset of [000 Eq. 6] and its standard error, %.
    """

    source: str
    analysis: CampaignAnalysis
    k_p_pct: float
    k_p_err_pct: float

    def overrides(self) -> tuple[dict[str, float], dict[str, float]]:
        """``[slip_overrides]`` values and their standard errors (paper units).

        Raises
        ------
        CalibrationError
            The pinch-force law could not be fitted (the reason is the evaluation's).
        """
        a = self.analysis
        pl = a.pinch_law
        if pl is None:
            raise CalibrationError("the records do not determine the pinch-force law [000 "
                                   f"Eq. 6]: {a.problems.get('pinch_law', 'no fit')}",
                                   source=self.source, field="pinch_force_set_n")
        values = {"k_s_pct_N": 100.0 * pl.k_s_n, "k_inf_pct_per_N": 100.0 * pl.k_inf_per_n}
        errors = {"k_s_pct_N": 100.0 * pl.k_s_err_n,
                  "k_inf_pct_per_N": 100.0 * pl.k_inf_err_per_n}
        vl = a.velocity_law
        if vl is not None and vl.velocity_dependent:
            assert vl.b_per_n is not None and vl.c_s_per_mm is not None
            assert vl.b_err_per_n is not None and vl.c_err_s_per_mm is not None
            values.update(a_pct_per_N=100.0 * vl.a_per_n, b_pct_per_N=100.0 * vl.b_per_n,
                          c_s_per_mm=vl.c_s_per_mm)
            errors.update(a_pct_per_N=100.0 * vl.a_err_per_n,
                          b_pct_per_N=100.0 * vl.b_err_per_n, c_s_per_mm=vl.c_err_s_per_mm)
        return values, errors

    def fragment(self, header: Sequence[str] = ()) -> str:
        """Drive-profile fragment: ``k_p_pct`` and ``[slip_overrides]`` (TOML).

        Raises
        ------
        CalibrationError
            A fitted value the drive profile does not accept (named, with the reason).
        """
        values, errors = self.overrides()
        try:
            SlipOverrides.model_validate(values)
        except ValidationError as exc:
            first = exc.errors()[0]
            field = ".".join(str(p) for p in first["loc"])
            raise CalibrationError(f"the fitted slip law is not a valid drive profile: "
                                   f"{first['msg']}", source=self.source, field=field,
                                   value=values.get(field), allowed="see docs/profiles.md"
                                   ) from exc
        a = self.analysis
        lines = [f"flowtwin calibrate fit-slip: roller {a.roller_id!r} from {self.source}",
                 f"{len(a.results)} records, {len(a.rejected)} without a slip regression; "
                 "± are 1-sigma errors", *header]
        vl = a.velocity_law
        if vl is not None and not vl.velocity_dependent:
            lines.append(f"no velocity dependence [000 Eq. 8]: {vl.reason} (a = "
                         f"{100 * vl.a_per_n:.4g} ± {100 * vl.a_err_per_n:.2g} %/N); a "
                         "velocity-dependent catalogue roller stays so")
        for name, text in a.problems.items():
            lines.append(f"not fitted ({name}): {text}")
        for name, value in values.items():
            if not errors[name] <= abs(value):
                lines.append(f"WARNING: the records do not determine {name} ({value:.4g} ± "
                             f"{errors[name]:.2g}); check it before use")
        mf = a.max_force
        if mf is not None:
            c0, c1, c2 = mf.coeffs
            lines.append(f"maximum feed force [000 Figs. 4-8]: {c0:.4g} + {c1:.4g}*Fp + "
                         f"{c2:.4g}*Fp^2 N over {min(mf.pinch_forces_n):g}-"
                         f"{max(mf.pinch_forces_n):g} N (a [custom_roller] "
                         "max_feed_force_fit)")
        lines.append("paste into the drive profile: k_p_pct at the top, the table in place "
                     "of its [slip_overrides]")
        head = "\n".join(f"# {ln}" for ln in lines)
        kp = (f"k_p_pct = {format_toml_value(round(self.k_p_pct, 6))}"
              f"   # ± {self.k_p_err_pct:.2g} (1σ)")
        table = render_fragment("slip_overrides", {k: round(v, 7) for k, v in values.items()},
                                stderr=errors)
        text = f"{head}\n{kp}\n\n{table}"
        tomllib.loads(text)
        return text

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able description."""
        a = self.analysis
        try:
            values, errors = self.overrides()
        except CalibrationError:
            values, errors = {}, {}
        mf = a.max_force
        return {
            "source": self.source, "roller_id": a.roller_id, "records": len(a.results),
            "rejected": len(a.rejected), "k_p_pct": self.k_p_pct,
            "k_p_err_pct": self.k_p_err_pct, "slip_overrides": values, "errors": errors,
            "velocity_dependent": (None if a.velocity_law is None
                                   else a.velocity_law.velocity_dependent),
            "max_force": None if mf is None else {"coeffs": list(mf.coeffs),
                                                  "errors": list(mf.errors)},
            "problems": dict(a.problems),
        }


def slip_calibration(analysis: CampaignAnalysis, *, source: str = "<records>"
                     ) -> SlipCalibration:
    """A :class:`SlipCalibration` from an evaluated campaign (adds ``k_p``).

    Raises
    ------
    CalibrationError
        No record has a slip regression.
    """
    offsets = np.array([r.slip.offset for r in analysis.results if r.slip is not None])
    if offsets.size == 0:
        raise CalibrationError("no record has a slip regression: "
                               + "; ".join(sorted({r.slip_problem or "" for r in
                                                   analysis.results})[:3]),
                               source=source, field="slip")
    err = float(np.std(offsets, ddof=1) / math.sqrt(offsets.size)) if offsets.size > 1 \
        else math.nan
    return SlipCalibration(source, analysis, 100.0 * float(np.mean(offsets)), 100.0 * err)


def fit_slip_records(path: str | os.PathLike[str], *, roller_id: str | None = None
                     ) -> SlipCalibration:
    """Evaluate a test-stand records file for one roller (:mod:`flowtwin.teststand`).

    Parameters
    ----------
    path
        Records CSV, schema 1 (docs/teststand.md).
    roller_id
        Roller to evaluate; may be left out when the file holds one roller.

    Returns
    -------
    SlipCalibration

    Raises
    ------
    DataError
        Unreadable or malformed file; an unknown roller, or several without ``roller_id``.
    CalibrationError
        No slip regression in any record.
    """
    name = os.fspath(path)
    records = read_records_csv(name)
    ids = sorted({r.key.roller_id for r in records})
    if roller_id is None:
        if len(ids) != 1:
            raise DataError("the file holds several rollers: name one", source=name,
                            field="roller_id", value=ids, allowed=", ".join(ids))
        roller_id = ids[0]
    if roller_id not in ids:
        raise DataError("no records of that roller in the file", source=name,
                        field="roller_id", value=roller_id, allowed=", ".join(ids))
    mine = [r for r in records if r.key.roller_id == roller_id]
    return slip_calibration(analyse_campaign(analyse_records(mine)), source=name)
