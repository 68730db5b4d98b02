"""Plot of a vision measurement: speeds, slip and width over time (PNG, Agg backend)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from flowtwin.atomic import atomic_write_bytes
from flowtwin.vision.readings import FILAMENT_INVALID, GEAR_INVALID, VisionResult

__all__ = ["plot_png", "write_plot"]


def plot_png(result: VisionResult, *, title: str | None = None) -> bytes:
    """Render the series as a three-panel PNG.

    Panels: gear and filament speed (raw points, smoothed lines [003 Eq. 5]); slip in %
    from the smoothed speeds; width in mm. Samples flagged invalid are not drawn; grey
    ticks at the bottom of the speed panel mark them.

    Parameters
    ----------
    result
        The measurement.
    title
        Figure title (default: the source).

    Returns
    -------
    bytes
        PNG file content.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    s = result.series
    t = s.t_s
    fig = Figure(figsize=(9.0, 7.5), dpi=100)
    FigureCanvasAgg(fig)
    ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
    ax1.plot(t, s.gear_speed_mm_s, ".", ms=2, color="tab:blue", alpha=0.4)
    ax1.plot(t, s.filament_speed_mm_s, ".", ms=2, color="tab:orange", alpha=0.4)
    ax1.plot(t, s.gear_speed_smooth_mm_s, color="tab:blue", label="gear (ω·R)")
    ax1.plot(t, s.filament_speed_smooth_mm_s, color="tab:orange", label="filament")
    bad = (s.flags & int(GEAR_INVALID | FILAMENT_INVALID)) != 0
    if bad.any():
        low = np.nanmin(np.concatenate([s.gear_speed_mm_s, s.filament_speed_mm_s, [0.0]]))
        ax1.plot(t[bad], np.full(int(bad.sum()), low), "|", color="0.5", label="flagged")
    ax1.set_ylabel("speed (mm/s)")
    ax1.legend(loc="best", fontsize=8)
    ax2.plot(t, 100.0 * s.slip, ".", ms=2, color="tab:red", alpha=0.3)
    ax2.plot(t, 100.0 * s.slip_smooth, color="tab:red")
    ax2.set_ylabel("slip (%)")
    ax3.plot(t, s.width_mm, ".", ms=2, color="tab:green", alpha=0.4)
    ax3.plot(t, s.width_smooth_mm, color="tab:green")
    ax3.set_ylabel("width (mm)")
    ax3.set_xlabel("time (s)")
    sm = result.summary
    fig.suptitle(title or sm.source, fontsize=10)
    ax1.set_title(f"gear {sm.gear_speed_mm_s:.3f} mm/s, filament {sm.filament_speed_mm_s:.3f} "
                  f"mm/s, slip {sm.slip_pct:.2f} %, width {sm.width_mm:.4f} mm, "
                  f"{sm.valid_frames}/{sm.frames} valid", fontsize=9)
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def write_plot(result: VisionResult, path: str | Path, *, title: str | None = None) -> None:
    """Write :func:`plot_png` to ``path`` atomically."""
    atomic_write_bytes(path, plot_png(result, title=title))
