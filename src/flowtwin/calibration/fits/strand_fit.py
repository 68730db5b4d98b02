"""Strand-shape model from measured profile points [004].

What to measure: the side profile of the strand between the nozzle exit and the bed while
printing a straight line at constant speed (a side camera or a frozen strand cut along
its axis, as [004 Fig. 3] did), as points ``(x_mm, z_mm)``: ``x`` the distance *behind*
the nozzle axis (the strand trails towards ``+x``), ``z`` the height above the layer
below. Give the nozzle height ``H`` above that layer (the layer height of the measurement).

The tractrix [004 Eq. 5], parabola [004 Eq. 6] and catenary [004 Eq. 7] are fitted with
:func:`flowtwin.physics.strand.fit_strand_profile`; ``model = "best"`` fits all three and
keeps the one with the smallest Bayesian information criterion (the RMS residual penalised
by the number of parameters; [004] found the tractrix best) whose parameters the points
determine. Uncertainties
come from the Jacobian of the residuals at the optimum (numerical, central differences):
``cov = s²·(JᵀJ)⁻¹``, ``s² = Σr²/(n − p)``.

The strand *lag* — how far behind the nozzle the strand reaches the bed, the ``L`` of the
nozzle trajectory ``P_N = P_i + L·t̂ + H·ẑ`` [004 Eqs. 9–11] — is the fitted ``L`` of the
parabola and catenary, and for the tractrix (which meets the bed only asymptotically) the
distance where it has sunk to 0.5 % of its height
(:func:`flowtwin.physics.strand.tractrix_contact_length_mm`) plus its shift.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.csvdata import Column, Table
from flowtwin.calibration.fits.fitting import propagate_std
from flowtwin.errors import CalibrationError, DataError
from flowtwin.physics.strand import (
    StrandFit,
    StrandModel,
    fit_strand_profile,
    tractrix_contact_length_mm,
)

__all__ = ["STRAND_COLUMNS", "StrandCalibration", "fit_strand", "strand_points"]

FloatArray = npt.NDArray[np.float64]

#: Columns of a strand-profile file.
STRAND_COLUMNS = (
    Column("x_mm", "distance behind the nozzle axis, mm", lower=-100.0, upper=100.0),
    Column("z_mm", "height above the layer below, mm", lower=0.0, upper=100.0),
)


def strand_points(table: Table) -> tuple[FloatArray, FloatArray]:
    """``(x_mm, z_mm)`` of a strand-profile table."""
    return table.get("x_mm"), table.get("z_mm")


@dataclass(frozen=True)
class StrandCalibration:
    """A fitted strand curve with 1σ uncertainties.

    Attributes
    ----------
    fit
        The curve (:class:`~flowtwin.physics.strand.StrandFit`).
    stderr
        1σ standard error of each parameter of ``fit.params``, mm.
    lag_mm
        Where the strand reaches the bed behind the nozzle, mm (see module docstring).
    lag_stderr_mm
        Its 1σ standard error, mm.
    n_points
        Number of profile points.
    rms_by_model
        RMS residual (mm) of every model tried.
    bic_by_model
        Bayesian information criterion ``n·ln(RMS²) + p·ln(n)`` of every model tried
        (smaller is better; ``"best"`` keeps the smallest whose parameters are determined).
    """

    fit: StrandFit
    stderr: dict[str, float]
    lag_mm: float
    lag_stderr_mm: float
    n_points: int
    rms_by_model: dict[str, float]
    bic_by_model: dict[str, float]

    def profile_table(self) -> dict[str, Any]:
        """The ``[strand]`` table of the profile fragment."""
        return {"model": self.fit.model.value, "height_mm": self.fit.height_mm,
                **self.fit.params, "lag_mm": self.lag_mm, "rms_mm": self.fit.rms_mm}

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able figures."""
        return {"model": self.fit.model.value, "height_mm": self.fit.height_mm,
                "params": dict(self.fit.params), "stderr": dict(self.stderr),
                "lag_mm": self.lag_mm, "lag_stderr_mm": self.lag_stderr_mm,
                "rms_mm": self.fit.rms_mm, "n_points": self.n_points,
                "rms_by_model": dict(self.rms_by_model),
                "bic_by_model": dict(self.bic_by_model)}


def _lag(fit: StrandFit) -> float:
    if fit.model is StrandModel.TRACTRIX:
        return float(tractrix_contact_length_mm(fit.params["r_mm"])) + fit.params["shift_mm"]
    return fit.params["length_mm"]


def _with(fit: StrandFit, name: str, value: float) -> StrandFit:
    return replace(fit, params={**fit.params, name: value})


def _uncertainty(fit: StrandFit, x: FloatArray, z: FloatArray
                 ) -> tuple[dict[str, float], float]:
    names = list(fit.params)
    n, p = x.size, len(names)
    jac = np.empty((n, p))
    lag_grad = np.empty(p)
    for j, name in enumerate(names):
        value = fit.params[name]
        step = 1e-6 * max(abs(value), fit.height_mm)
        up, down = _with(fit, name, value + step), _with(fit, name, value - step)
        jac[:, j] = (up.z_mm(x) - down.z_mm(x)) / (2.0 * step)
        lag_grad[j] = (_lag(up) - _lag(down)) / (2.0 * step)
    resid = fit.z_mm(x) - z
    s2 = float(resid @ resid) / (n - p)
    jtj = jac.T @ jac
    if not np.all(np.isfinite(jtj)) or np.linalg.matrix_rank(jtj) < p:
        raise CalibrationError(f"the {fit.model.value} strand fit is degenerate: its "
                               "parameters are not determined separately by the points",
                               field=",".join(names))
    cov = np.asarray(s2 * np.linalg.inv(jtj), dtype=np.float64)
    errs = np.sqrt(np.diag(cov))
    stderr = dict(zip(names, errs.tolist(), strict=True))
    for name, err in stderr.items():
        value = fit.params[name]
        if name != "shift_mm" and not err <= abs(value):
            raise CalibrationError(f"the {fit.model.value} strand fit does not determine "
                                   f"{name}: {value:.4g} ± {err:.2g} mm", field=name,
                                   value=value, allowed="standard error <= |value|")
    return stderr, propagate_std(lag_grad, cov)


def fit_strand(x_mm: npt.ArrayLike, z_mm: npt.ArrayLike, *, height_mm: float,
               model: StrandModel | Literal["best"] = "best") -> StrandCalibration:
    """Fit a strand curve of [004] to profile points, with uncertainties.

    Parameters
    ----------
    x_mm
        Distance behind the nozzle of each point, mm, shape ``(n,)``.
    z_mm
        Height above the layer below, mm, shape ``(n,)``.
    height_mm
        Nozzle height ``H`` above the layer below, mm.
    model
        Curve to fit, or ``"best"`` (all three, smallest RMS kept).

    Returns
    -------
    StrandCalibration

    Raises
    ------
    DataError
        Fewer than 4 points, or points that cannot be a profile.
    CalibrationError
        A fit that does not converge, is degenerate, or ends its bed contact ``L`` at the
        last measured point (the profile does not reach the bed).
    """
    x = np.asarray(x_mm, dtype=np.float64)
    z = np.asarray(z_mm, dtype=np.float64)
    if x.ndim != 1 or x.shape != z.shape or x.size < 4:
        raise DataError("a strand profile needs at least 4 points (x_mm, z_mm)",
                        field="x_mm", value=x.size, allowed=">= 4 points")
    models = list(StrandModel) if model == "best" else [StrandModel(model)]
    fits: dict[str, StrandFit] = {}
    failures: dict[str, str] = {}
    for m in models:
        try:
            fits[m.value] = fit_strand_profile(x, z, model=m, height_mm=height_mm)
        except CalibrationError as exc:
            failures[m.value] = exc.message
    if not fits:
        raise CalibrationError("no strand model could be fitted: " + "; ".join(
            f"{k}: {v}" for k, v in failures.items()), field="model")
    n = x.size
    # rank by the Bayesian information criterion n·ln(RMS²) + p·ln(n): the 3-parameter
    # catenary can always bend closer to the points than the 1-parameter parabola
    bic = {k: n * np.log(max(f.rms_mm, 1e-300) ** 2) + len(f.params) * np.log(n)
           for k, f in fits.items()}
    last_error: CalibrationError | None = None
    for key in sorted(fits, key=lambda k: bic[k]):
        fit = fits[key]
        try:
            if fit.model is not StrandModel.TRACTRIX and \
                    fit.params["length_mm"] >= float(np.max(x)) * (1.0 - 1e-6):
                raise CalibrationError(
                    f"the {key} fit puts the bed contact at the last measured point: the "
                    "profile does not reach the bed", field="x_mm", value=float(np.max(x)),
                    allowed="points measured beyond the strand's bed contact")
            stderr, lag_err = _uncertainty(fit, x, z)
        except CalibrationError as exc:
            last_error = exc       # "best": try the next model; one model: report it
            continue
        return StrandCalibration(fit, stderr, _lag(fit), lag_err, int(n),
                                 {k: f.rms_mm for k, f in fits.items()},
                                 {k: float(v) for k, v in bic.items()})
    assert last_error is not None
    raise last_error
