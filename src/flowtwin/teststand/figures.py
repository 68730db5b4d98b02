"""Figures of a test-stand evaluation in the style of [000 Figs. 4–11] (matplotlib, Agg).

Every ``plot_*`` function draws on an ``Axes`` it is given, so callers compose panels;
:func:`new_figure` makes a figure without pyplot's global state and :func:`save_figure`
writes it as PNG atomically (no timestamp in the file, so reruns give identical bytes).
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from flowtwin.atomic import atomic_write_bytes
from flowtwin.errors import CalibrationError
from flowtwin.physics.drive import max_feed_force_n, measured_slip
from flowtwin.profiles import Roller
from flowtwin.teststand.analysis import RecordResult
from flowtwin.teststand.fits import MaxForceFit, PinchLawFit, VelocityLawFit
from flowtwin.teststand.records import Record

__all__ = [
    "new_figure",
    "plot_max_force",
    "plot_pinch_law",
    "plot_r_squared_histogram",
    "plot_slip_record",
    "plot_velocity_law",
    "save_figure",
]


def new_figure(width_in: float = 6.4, height_in: float = 4.2, *, rows: int = 1,
               cols: int = 1) -> tuple[Figure, list[Axes]]:
    """A figure with an Agg canvas and ``rows × cols`` axes (flattened, row-major)."""
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False)
    return fig, [ax for row in axes for ax in row]


def save_figure(fig: Figure, path: str | os.PathLike[str], *, dpi: int = 110) -> Path:
    """Write ``fig`` as PNG to ``path`` atomically; returns the path."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    atomic_write_bytes(path, buf.getvalue())
    return Path(path)


def _speed_sizes(speeds: np.ndarray) -> np.ndarray:
    """Marker areas growing with the feed velocity, as in [000 Figs. 4–8, 10]."""
    return 8.0 + 6.0 * np.sqrt(np.asarray(speeds, dtype=np.float64))


def plot_slip_record(ax: Axes, record: Record, result: RecordResult) -> None:
    """Measured slip against feed force of one record with its regression [000 Fig. 9a]."""
    if result.slip is None:
        raise CalibrationError(f"the record has no slip regression to plot: "
                               f"{result.slip_problem}", field="slip",
                               value=record.key.describe())
    n = result.slip.n_samples
    force = record.feed_force_n[:n]
    slip_pct = 100.0 * measured_slip(record.key.nominal_speed_mm_s,
                                     record.filament_speed_mm_s[:n])
    ax.scatter(force, slip_pct, s=4, color="tab:orange", alpha=0.6, label="measured $s_m$")
    f = np.linspace(0.0, float(force.max()), 50)
    g = 100.0 * result.slip.gradient_per_n
    ax.plot(f, 100.0 * result.slip.offset + g * f, color="black",
            label=f"fit: $s'$ = {g:.3f} %/N, offset {100 * result.slip.offset:.2f} %")
    ax.set_xlabel("feed force $F_f$ (N)")
    ax.set_ylabel("slip $s_m$ (%)")
    ax.set_title(record.key.describe())
    ax.legend(loc="upper left", fontsize=8)


def plot_r_squared_histogram(ax: Axes, results: Sequence[RecordResult], *,
                             bins: int = 20) -> None:
    """Histogram of the regressions' ``R²`` [000 Fig. 9b]."""
    r2 = np.array([r.slip.r_squared for r in results if r.slip is not None])
    ax.hist(np.clip(r2, 0.0, 1.0), bins=bins, range=(0.0, 1.0), color="tab:blue",
            edgecolor="white")
    ax.set_xlabel("coefficient of determination $R^2$")
    ax.set_ylabel("records")
    ax.set_title(f"{r2.size} slip regressions, median $R^2$ = {np.median(r2):.3f}")


def plot_pinch_law(ax: Axes, results: Sequence[RecordResult], fit: PinchLawFit | None, *,
                   roller: Roller | None = None) -> None:
    """Slip gradient against pinch force with the Eq. 6 fit [000 Fig. 10]."""
    ok = [r for r in results if r.slip is not None]
    fp = np.array([r.key.pinch_force_set_n for r in ok])
    g = np.array([100.0 * r.slip_gradient_per_n for r in ok])
    v = np.array([r.key.nominal_speed_mm_s for r in ok])
    ax.scatter(fp, g, s=_speed_sizes(v), alpha=0.5, color="tab:orange",
               label="records (marker area ~ speed)")
    grid = np.linspace(max(1.0, float(fp.min()) if fp.size else 10.0),
                       float(fp.max()) if fp.size else 150.0, 200)
    if fit is not None:
        ax.plot(grid, 100.0 * fit.gradient_per_n(grid), color="black",
                label=f"fit: $k_s$ = {100 * fit.k_s_n:.1f} %N, "
                      f"$k_\\infty$ = {100 * fit.k_inf_per_n:.3f} %/N")
    if roller is not None:
        ax.plot(grid, roller.k_s_pct_N / grid ** 2 + roller.k_inf_pct_per_N, "--",
                color="tab:blue", label="[000] Table 3")
    ax.set_xlabel("pinch force $F_p$ (N)")
    ax.set_ylabel("slip gradient $s'$ (%/N)")
    ax.legend(fontsize=8)


def plot_velocity_law(ax: Axes, results: Sequence[RecordResult], fit: VelocityLawFit | None,
                      *, roller: Roller | None = None,
                      pinch_range_n: tuple[float, float] = (80.0, 130.0)) -> None:
    """Slip gradient against feed velocity at 80–130 N with the Eq. 8 fit [000 Fig. 11]."""
    lo, hi = pinch_range_n
    ok = [r for r in results if r.slip is not None and lo <= r.key.pinch_force_set_n <= hi]
    v = np.array([r.key.nominal_speed_mm_s for r in ok])
    g = np.array([100.0 * r.slip_gradient_per_n for r in ok])
    ax.scatter(v, g, s=10, alpha=0.4, color="tab:orange", label="records")
    for speed in sorted(set(v.tolist())):
        sel = g[v == speed]
        ax.errorbar([speed], [sel.mean()], yerr=[sel.std()], fmt="o", color="tab:red",
                    capsize=3)
    grid = np.linspace(0.0, float(v.max()) if v.size else 15.0, 200)
    if fit is not None:
        label = (f"fit: a={100 * fit.a_per_n:.3f}, b={100 * fit.b_per_n:.3f} %/N, "
                 f"c={fit.c_s_per_mm:.3f} s/mm" if fit.velocity_dependent and
                 fit.b_per_n is not None and fit.c_s_per_mm is not None
                 else f"fit: s' = a = {100 * fit.a_per_n:.3f} %/N (no velocity term)")
        ax.plot(grid, 100.0 * fit.gradient_per_n(grid), color="black", label=label)
    if roller is not None and roller.a_pct_per_N is not None:
        pub = np.full_like(grid, roller.a_pct_per_N)
        if roller.velocity_dependent and roller.b_pct_per_N is not None and \
                roller.c_s_per_mm is not None:
            pub = pub + roller.b_pct_per_N * np.exp(-roller.c_s_per_mm * grid)
        ax.plot(grid, pub, "--", color="tab:blue", label="[000] Table 3")
    ax.set_xlabel("feed velocity $v_{fil}$ (mm/s)")
    ax.set_ylabel("slip gradient $s'$ (%/N)")
    ax.set_title(f"pinch force {lo:g}-{hi:g} N")
    ax.legend(fontsize=8)


def plot_max_force(ax: Axes, results: Sequence[RecordResult], fit: MaxForceFit | None, *,
                   roller: Roller | None = None) -> None:
    """Maximum feed force against pinch force with the 2nd-order fit [000 Figs. 4–8]."""
    fp = np.array([r.key.pinch_force_set_n for r in results])
    fmax = np.array([r.max_feed_force_n for r in results])
    v = np.array([r.key.nominal_speed_mm_s for r in results])
    ax.scatter(fp, fmax, s=_speed_sizes(v), alpha=0.4, color="tab:orange",
               label="records (marker area ~ speed)")
    grid = np.linspace(float(fp.min()) if fp.size else 10.0,
                       float(fp.max()) if fp.size else 150.0, 200)
    if fit is not None:
        c0, c1, c2 = fit.coeffs
        ax.plot(grid, fit.max_feed_force_n(grid), color="black",
                label=f"fit: {c2:.3g} $F_p^2$ + {c1:.3g} $F_p$ + {c0:.3g}")
    if roller is not None and roller.max_feed_force_fit is not None:
        m = roller.max_feed_force_fit
        ax.plot(grid, max_feed_force_n(grid, (m.c0_N, m.c1, m.c2_per_N)), "--",
                color="tab:blue", label=f"{m.figure or '[000]'}")
    ax.set_xlabel("pinch force $F_p$ (N)")
    ax.set_ylabel("maximum feed force $F_{f,max}$ (N)")
    ax.legend(fontsize=8)
