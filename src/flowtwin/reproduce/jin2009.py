"""[004] Jin, Zhang, Wang, Zhu 2009: strand shape and nozzle trajectory — claims and figures.

Strand curves and fits from :mod:`flowtwin.physics.strand`, nozzle trajectories from
:mod:`flowtwin.physics.nozzle_path` and the clamped spline of Eqs. 20–21 from
:mod:`flowtwin.physics.spline`; the paper's simulation values ``H = 0.012``, ``L = 0.06``
(mm) [004 Fig. 7].
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from flowtwin.physics.nozzle_path import (
    NozzleTrajectory,
    circle_nozzle_phase_rad,
    circle_nozzle_radius_mm,
    nozzle_positions_mm,
    nozzle_trajectory_for_graph_road,
)
from flowtwin.physics.spline import clamped_spline
from flowtwin.physics.strand import (
    StrandModel,
    fit_strand_profile,
    parabola_z_mm,
    tractrix_x_mm,
    tractrix_z_mm,
)
from flowtwin.reproduce.claims import Claim, Outcome, rounded
from flowtwin.reproduce.context import ReproContext
from flowtwin.reproduce.figures import FigureSpec, PaperSection
from flowtwin.teststand.figures import new_figure

__all__ = ["SECTION"]

PAPER = "jin2009"
#: Nozzle height and strand lag of [004 Fig. 7], mm.
H_MM, L_MM = 0.012, 0.06
#: Circle road radius for the circle claims, mm (Fig. 7b gives none in the text).
R_CIRCLE_MM = 1.0
#: Nodes of the polynomial road y = x⁴ + x³ + x² + x on [0, 1] (Fig. 7c; range not given).
X_NODES = np.linspace(0.0, 1.0, 11)
_ENGINE = "flowtwin.physics.nozzle_path"


def _poly(x: np.ndarray) -> np.ndarray:
    return x ** 4 + x ** 3 + x ** 2 + x


def _dpoly(x: np.ndarray) -> np.ndarray:
    return 4 * x ** 3 + 3 * x ** 2 + 2 * x + 1


def _d2poly(x: np.ndarray) -> np.ndarray:
    return 12 * x ** 2 + 6 * x + 2


def polynomial_trajectory(samples: int = 201) -> NozzleTrajectory:
    """The nozzle path for the road of [004 Fig. 7c] (paper's spline, Eqs. 20–21)."""
    return nozzle_trajectory_for_graph_road(
        X_NODES, _poly(X_NODES), dy_start=float(_dpoly(np.array(0.0))),
        dy_end=float(_dpoly(np.array(1.0))), lag_mm=L_MM, height_mm=H_MM,
        x_samples=np.linspace(0.0, 1.0, samples))


def synthetic_profile(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A 'measured' strand: the tractrix of H = 0.012 mm sampled at 240 heights with 1 % noise.

    [004] sampled 240 points of a photographed strand over the layer height; the photo is
    not in the seed, so the fit machinery is shown on a tractrix with measurement noise of
    1 % of H.
    """
    z = H_MM * np.arange(1, 241) / 240.0
    x = tractrix_x_mm(z, H_MM)
    rng = np.random.default_rng(seed)
    return x, z + 0.01 * H_MM * rng.standard_normal(z.size)


def _tractrix_ode(ctx: ReproContext) -> Outcome:
    z = H_MM * np.linspace(0.02, 0.98, 97)
    step = 1e-6 * H_MM
    dxdz = (tractrix_x_mm(z + step, H_MM) - tractrix_x_mm(z - step, H_MM)) / (2 * step)
    eq1 = -np.sqrt(H_MM ** 2 - z ** 2) / z
    err = float(np.max(np.abs(dxdz / eq1 - 1.0)))
    return Outcome("dx/dz = −sqrt(H² − z²)/z", float(f"{err:.2g}"),
                   "largest relative deviation <= 1e-6 (central differences of step 1e-6·H)",
                   err <= 1e-6, "Eq. 5 differentiated numerically against Eq. 1, z = 0.02-0.98 H")


def _tangent_length(ctx: ReproContext) -> Outcome:
    x = np.linspace(0.001, 6.0, 200) * H_MM
    step = 1e-7 * H_MM
    z = tractrix_z_mm(x, H_MM)
    slope = (tractrix_z_mm(x + step, H_MM) - tractrix_z_mm(x - step, H_MM)) / (2 * step)
    length = np.hypot(z, z / slope)
    err = float(np.max(np.abs(length / H_MM - 1.0)))
    return Outcome(H_MM, rounded([float(length.min()), float(length.max())], 8),
                   "every tangent segment to the bed equals H within 1e-6", err <= 1e-6,
                   "z(x) from flowtwin's inverted tractrix (x = H(t − tanh t), z = H sech t), "
                   "tangent from numerical slopes, x = 0-6 H")


def _fit_ranking(ctx: ReproContext) -> Outcome:
    x, z = synthetic_profile(ctx.seed)
    fits = {m: fit_strand_profile(x, z, model=m, height_mm=H_MM) for m in StrandModel}
    rms = {m.value: fits[m].rms_mm for m in StrandModel}
    order = sorted(rms, key=rms.__getitem__)
    r_fit = fits[StrandModel.TRACTRIX].params["r_mm"]
    ok = order == ["tractrix", "catenary", "parabola"] and abs(r_fit / H_MM - 1) <= 0.02
    return Outcome("tractrix < catenary < parabola", " < ".join(order),
                   "same ranking of the RMS residual; tractrix r within 2 % of H", ok,
                   "RMS (µm): " + ", ".join(f"{k} {1000 * v:.2f}" for k, v in rms.items())
                   + f"; fitted r = {1000 * r_fit:.2f} µm. The measured curve of Fig. 3 is "
                   "not in the seed: the profile is a tractrix with 1 % noise")


def _circle_points() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    alpha = np.linspace(0.0, 2.0 * math.pi, 73)
    road = R_CIRCLE_MM * np.column_stack([np.cos(alpha), np.sin(alpha)])
    tangent = np.column_stack([-np.sin(alpha), np.cos(alpha)])
    return alpha, road, nozzle_positions_mm(road, tangent, lag_mm=L_MM, height_mm=H_MM)


def _circle_radius(ctx: ReproContext) -> Outcome:
    _, _, nozzle = _circle_points()
    radius = np.hypot(nozzle[:, 0], nozzle[:, 1])
    paper = math.sqrt(R_CIRCLE_MM ** 2 + L_MM ** 2)
    err = float(np.max(np.abs(radius / paper - 1.0)))
    closed = float(circle_nozzle_radius_mm(R_CIRCLE_MM, L_MM))
    return Outcome(round(paper, 10), round(float(radius.max()), 10),
                   "every nozzle point within 1e-12 (relative) of sqrt(r² + L²)",
                   err <= 1e-12 and abs(closed - paper) <= 1e-12 * paper,
                   f"general construction P_N = P + L·t̂ + H·ẑ [Eq. 19] on a circle of r = "
                   f"{R_CIRCLE_MM:g} mm, L = {L_MM} mm; circle_nozzle_radius_mm gives "
                   f"{closed:.10f}")


def _circle_phase(ctx: ReproContext) -> Outcome:
    alpha, _, nozzle = _circle_points()
    lead = np.angle(np.exp(1j * (np.arctan2(nozzle[:, 1], nozzle[:, 0]) - alpha)))
    paper = math.atan(L_MM / R_CIRCLE_MM)
    err = float(np.max(np.abs(lead - paper)))
    return Outcome(round(paper, 10), round(float(lead.mean()), 10),
                   "lead angle within 1e-12 rad at every point", err <= 1e-12 and abs(
                       float(circle_nozzle_phase_rad(R_CIRCLE_MM, L_MM)) - paper) <= 1e-12,
                   "the nozzle leads the laid point by γ = atan(L/r) [Eq. 15]")


def _straight_line(ctx: ReproContext) -> Outcome:
    theta = math.radians(30.0)
    s = np.linspace(0.0, 5.0, 51)
    road = np.column_stack([s * math.cos(theta), s * math.sin(theta)])
    tangent = np.tile([math.cos(theta), math.sin(theta)], (s.size, 1))
    nozzle = nozzle_positions_mm(road, tangent, lag_mm=L_MM, height_mm=H_MM)
    eq10 = np.column_stack([(L_MM + s) * math.cos(theta), (L_MM + s) * math.sin(theta),
                            np.full_like(s, H_MM)])
    err = float(np.max(np.abs(nozzle - eq10)))
    return Outcome("((L + vt)cos θ, (L + vt)sin θ, H)", float(f"{err:.2g}"),
                   "largest deviation from Eq. 10 <= 1e-12 mm", err <= 1e-12,
                   "straight road at 30°, L = 0.06 mm, H = 0.012 mm")


def _poly_offset(ctx: ReproContext) -> Outcome:
    traj = polynomial_trajectory()
    d = np.hypot(*(traj.nozzle_xyz_mm[:, :2] - traj.road_xy_mm).T)
    err = float(np.max(np.abs(d - L_MM)))
    z_ok = bool(np.all(traj.nozzle_xyz_mm[:, 2] == H_MM))
    return Outcome(L_MM, rounded([float(d.min()), float(d.max())], 10),
                   "|P_N − P_i| = L within 1e-12 mm and z = H at every sample",
                   err <= 1e-12 and z_ok,
                   "y = x⁴ + x³ + x² + x on [0, 1], 11 nodes, clamped spline of Eqs. 20–21")


def _poly_difference(ctx: ReproContext) -> Outcome:
    traj = polynomial_trajectory()
    xd = np.linspace(-0.2, 1.2, 140001)
    tree = cKDTree(np.column_stack([xd, _poly(xd)]))
    offset, _ = tree.query(traj.nozzle_xyz_mm[:, :2])
    xs = traj.road_xy_mm[:, 0]
    kappa = np.abs(_d2poly(xs)) / (1 + _dpoly(xs) ** 2) ** 1.5
    estimate = float(np.max(L_MM ** 2 * kappa / 2.0))
    got = float(offset.max())
    ok = abs(got / estimate - 1.0) <= 0.05 and got < 0.05 * L_MM
    return Outcome("a small difference", round(got, 6),
                   f"= L²κ_max/2 = {estimate:.6f} mm within 5 % (the next term is ~Lκ = "
                   f"{L_MM * float(kappa.max()):.2f} of it) and below 5 % of L", ok,
                   f"largest distance of the nozzle path from the road: {got * 1000:.2f} µm, "
                   f"{100 * got / L_MM:.1f} % of L")


def _spline_library(ctx: ReproContext) -> Outcome:
    xs = np.linspace(0.0, 1.0, 401)
    paper = clamped_spline(X_NODES, _poly(X_NODES), dy_start=1.0, dy_end=10.0)
    lib = CubicSpline(X_NODES, _poly(X_NODES), bc_type=((1, 1.0), (1, 10.0)))
    dy = float(np.max(np.abs(paper(xs) - lib(xs))))
    ds = float(np.max(np.abs(paper.derivative(xs) - lib(xs, 1))))
    return Outcome(0.0, rounded([dy, ds], 3),
                   "values and slopes agree within 1e-12 (rounding)", dy <= 1e-12 and ds <= 1e-12,
                   "Eqs. 20–21 (flowtwin.physics.spline) against scipy.interpolate.CubicSpline "
                   "with the same end slopes, 401 points")


def _spline_exact(ctx: ReproContext) -> Outcome:
    xs = np.linspace(0.0, 1.0, 2001)
    paper = clamped_spline(X_NODES, _poly(X_NODES), dy_start=1.0, dy_end=10.0)
    err = float(np.max(np.abs(paper(xs) - _poly(xs))))
    h = float(X_NODES[1] - X_NODES[0])
    bound = 5.0 / 384.0 * h ** 4 * 24.0
    return Outcome(round(bound, 10), float(f"{err:.4g}"),
                   "error <= (5/384)·h⁴·max|F''''| (Hall & Meyer 1976)", err <= bound,
                   "clamped spline of Eqs. 20–21 against y = x⁴ + x³ + x² + x, h = 0.1")


CLAIMS: tuple[Claim, ...] = (
    Claim(PAPER, "tractrix-eq1", "Eq. 5 is the tractrix: it solves Eq. 1",
          "[004 Eqs. 1–5]", _tractrix_ode, figure="strand",
          engine="flowtwin.physics.strand.tractrix_x_mm"),
    Claim(PAPER, "tractrix-tangent", "The tractrix's tangent segment to the bed has the "
          "constant length H", "[004 Eqs. 1–5]", _tangent_length, unit="mm", figure="strand",
          engine="flowtwin.physics.strand.tractrix_z_mm"),
    Claim(PAPER, "strand-fit-ranking", "Tractrix, catenary and parabola fitted to a strand: "
          "the tractrix fits best, the parabola worst", "[004 Fig. 3]", _fit_ranking,
          figure="strand", engine="flowtwin.physics.strand.fit_strand_profile"),
    Claim(PAPER, "line-road", "A straight road needs the same line shifted by L", "[004 "
          "Eqs. 8–11]", _straight_line, unit="mm", figure="trajectories", engine=_ENGINE),
    Claim(PAPER, "circle-radius", "A circle road of radius r needs a nozzle circle of radius "
          "sqrt(r² + L²)", "[004 Eq. 15]", _circle_radius, unit="mm", figure="trajectories",
          engine=_ENGINE),
    Claim(PAPER, "circle-phase", "On the circle the nozzle leads by atan(L/r)",
          "[004 Eqs. 13–16]", _circle_phase, unit="rad", figure="trajectories",
          engine=_ENGINE),
    Claim(PAPER, "fig7c-offset", "Fig. 7c (H = 0.012, L = 0.06): the nozzle is L ahead of "
          "the road along its tangent", "[004 Eq. 19, Fig. 7c]", _poly_offset, unit="mm",
          figure="trajectories", engine=_ENGINE),
    Claim(PAPER, "fig7c-small-difference", "Fig. 7c: nozzle trajectory and road differ only "
          "a little", "[004 Fig. 7c]", _poly_difference, unit="mm", figure="trajectories",
          engine=_ENGINE),
    Claim(PAPER, "spline-vs-library", "The clamped spline of Eqs. 20–21 equals a library "
          "clamped cubic spline", "[004 Eqs. 20–21]", _spline_library, figure="trajectories",
          engine="flowtwin.physics.spline.clamped_spline"),
    Claim(PAPER, "spline-accuracy", "The clamped spline reproduces the road within the "
          "classical error bound", "[004 Eqs. 20–21]", _spline_exact, unit="mm",
          engine="flowtwin.physics.spline.clamped_spline"),
)


def _fig_strand(ctx: ReproContext) -> Figure:
    x, z = synthetic_profile(ctx.seed)
    fig, (ax,) = new_figure(7.0, 4.0)
    ax.plot(1000 * x, 1000 * z, ".", ms=3, color="0.5", label="profile (tractrix + 1 % noise)")
    xx = np.linspace(0.0, float(x.max()), 300)
    for model in StrandModel:
        fit = fit_strand_profile(x, z, model=model, height_mm=H_MM)
        ax.plot(1000 * xx, 1000 * fit.z_mm(xx), label=f"{model.value} fit "
                f"(RMS {1000 * fit.rms_mm:.2f} µm)")
    ax.plot(1000 * xx, 1000 * parabola_z_mm(xx, H_MM, L_MM), ":", color="0.3",
            label=f"parabola Eq. 6 with L = {L_MM} mm (Fig. 7's L)")
    ax.set_xlabel("distance behind the nozzle x (µm)")
    ax.set_ylabel("height z (µm)")
    ax.set_title(f"strand models, H = {1000 * H_MM:.0f} µm (Fig. 3 style)")
    ax.legend(fontsize=7)
    return fig


def _fig_trajectories(ctx: ReproContext) -> Figure:
    fig, (a, b, c) = new_figure(13.0, 4.2, cols=3)
    theta = math.radians(30.0)
    s = np.linspace(0.0, 0.3, 2)
    a.plot(s * math.cos(theta), s * math.sin(theta), label="road")
    a.plot((s + L_MM) * math.cos(theta), (s + L_MM) * math.sin(theta), "--", label="nozzle")
    a.set_title("(a) straight road (Eq. 11)")
    a.set_aspect("equal")
    _, road, nozzle = _circle_points()
    b.plot(road[:, 0], road[:, 1], label=f"road, r = {R_CIRCLE_MM:g} mm")
    b.plot(nozzle[:, 0], nozzle[:, 1], "--", label="nozzle, sqrt(r² + L²)")
    b.set_title("(b) circle road (Eq. 15)")
    b.set_aspect("equal")
    traj = polynomial_trajectory()
    c.plot(traj.road_xy_mm[:, 0], traj.road_xy_mm[:, 1], label="road y = x⁴+x³+x²+x")
    c.plot(traj.nozzle_xyz_mm[:, 0], traj.nozzle_xyz_mm[:, 1], "--", label="nozzle")
    c.plot(X_NODES, _poly(X_NODES), "o", ms=3, color="black", label="spline nodes")
    inset = c.inset_axes((0.08, 0.45, 0.4, 0.4))
    sel = traj.road_xy_mm[:, 0] < 0.15
    inset.plot(traj.road_xy_mm[sel, 0], traj.road_xy_mm[sel, 1])
    inset.plot(traj.nozzle_xyz_mm[sel, 0], traj.nozzle_xyz_mm[sel, 1], "--")
    inset.set_xticks([])
    inset.set_yticks([])
    c.set_title("(c) y = x⁴+x³+x²+x (Eqs. 19–21)")
    for ax in (a, b, c):
        ax.set_xlabel("x (mm)")
        ax.legend(fontsize=7, loc="lower right")
    a.set_ylabel("y (mm)")
    return fig


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("strand", "[004 Fig. 3] strand curves: tractrix, parabola and catenary "
                         "fitted to a profile, and the parabola of Eq. 6 with L = 0.06 mm.",
               _fig_strand),
    FigureSpec("trajectories", "[004 Fig. 7] roads and nozzle trajectories for a straight "
                               "line, a circle and y = x⁴ + x³ + x² + x (inset: zoom near "
                               "the start), H = 0.012 mm, L = 0.06 mm.", _fig_trajectories),
)


def notes(ctx: ReproContext) -> list[str]:
    """Findings beyond the rows."""
    return [
        "Eq. 7 prints the catenary's constant as 1 − H, which adds 1 mm to a 0.012 mm height; "
        "flowtwin takes the constant that puts the curve through (0, H), like the parabola "
        "(flowtwin.physics.strand). Eq. 21's first term is printed with a minus sign; the "
        "spline that interpolates its nodes has a plus, and that is the one that agrees with "
        "the library spline above.",
    ]


SECTION = PaperSection(PAPER, "Jin, Zhang, Wang, Zhu: Filament geometrical model and nozzle "
                              "trajectory analysis in the fused deposition modeling process. "
                              "J Zhejiang Univ Sci A 2009", "004", CLAIMS, FIGURES, notes)
