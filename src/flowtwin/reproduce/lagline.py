"""The Marlin K-factor test line of [001] as a commanded feed, and the lag around it.

[001] prints the Marlin linear-advance calibration pattern (Marlin Firmware 2018, "K-factor
calibration pattern") and simulates it (Figs. 10–13). Its line speeds, accelerations and
lengths are drawn in [001 Fig. 10], not given in the text; this module uses the pattern
generator's defaults (MarlinDocumentation ``_tools/lin_advance/k-factor.html``): 20 mm at
20 mm/s, 40 mm at 70 mm/s, 20 mm at 20 mm/s, acceleration 500 mm/s², line width 1.2 × the
0.4 mm nozzle = 0.48 mm — the width of [001 Table I] — and 0.2 mm layers. The printer
accelerates inside the fast segment from the slow speed (collinear junctions pass at full
speed) and decelerates back before its end; the line starts and ends at rest.

The commanded filament speed is ``v0 = A_bead·v_print/A_fil`` [001 Eq. 7], piecewise
linear in time. Linear advance [001 Eq. 11] adds ``K_LA·dv0/dt`` (:func:`advance_feed`), the
discrete form [001 Eq. 13] ``ΔD_n = K_LA·(ΔD0_n/Δt − ΔD0_(n−1)/Δt) + ΔD0_n`` steps it
(:func:`discrete_advance_feed`). The extruder's response is computed by
:func:`flowtwin.dynamics.integrate` — the project's exact integrator of the lag with no
backflow [001 Eq. 10, Fig. 8]. :func:`linear_lag_response` is the *uncorrected* lag of
[001 Fig. 7] (negative output allowed), the exact lag step of :mod:`flowtwin.physics.lag`
on each segment, for comparison with Fig. 8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics import ExtrusionParams, integrate
from flowtwin.dynamics.feed import PHASE_ACCEL, PHASE_CRUISE, PHASE_DECEL, CommandedFeed
from flowtwin.errors import DataError
from flowtwin.physics.deposition import bead_area_mm2
from flowtwin.physics.lag import lag_linear
from flowtwin.physics.units import circle_area_mm2

__all__ = [
    "KFactorLine",
    "LineResponse",
    "advance_feed",
    "discrete_advance_feed",
    "linear_lag_response",
    "respond",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class KFactorLine:
    """One test line of the Marlin K-factor pattern (defaults of the pattern generator).

    Attributes
    ----------
    slow_mm_s, fast_mm_s
        Print speeds, mm/s.
    slow_length_mm, fast_length_mm
        Lengths of the slow and fast segments, mm (slow–fast–slow).
    accel_mm_s2
        Printing acceleration, mm/s².
    line_width_mm, layer_height_mm
        Bead size, mm ([001 Table I]: 0.48 mm; 0.1/0.2/0.3 mm layers).
    filament_diameter_mm
        Filament diameter, mm.
    """

    slow_mm_s: float = 20.0
    fast_mm_s: float = 70.0
    slow_length_mm: float = 20.0
    fast_length_mm: float = 40.0
    accel_mm_s2: float = 500.0
    line_width_mm: float = 0.48
    layer_height_mm: float = 0.2
    filament_diameter_mm: float = 1.75

    def __post_init__(self) -> None:
        ramp_slow = self.slow_mm_s ** 2 / (2 * self.accel_mm_s2)
        ramp_fast = (self.fast_mm_s ** 2 - self.slow_mm_s ** 2) / (2 * self.accel_mm_s2)
        if not (0 < self.slow_mm_s < self.fast_mm_s and ramp_slow < self.slow_length_mm
                and 2 * ramp_fast < self.fast_length_mm):
            raise DataError("the test line cannot reach its speeds within its segments",
                            field="fast_length_mm", value=self.fast_length_mm,
                            allowed=f"> {2 * ramp_fast:g} mm and slow < fast")

    @property
    def e_per_mm(self) -> float:
        """Filament per mm of path, ``A_bead/A_fil`` [001 Eq. 7]."""
        return float(bead_area_mm2(self.line_width_mm, self.layer_height_mm)
                     / circle_area_mm2(self.filament_diameter_mm))

    def phases(self) -> tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.int8]]:
        """Print-speed phases: durations (s), start speeds (mm/s), accelerations (mm/s²), kind.

        Seven phases: 0→slow, slow cruise, slow→fast, fast cruise, fast→slow, slow cruise,
        slow→0.
        """
        a, vs, vf = self.accel_mm_s2, self.slow_mm_s, self.fast_mm_s
        ramp_s = vs * vs / (2 * a)
        ramp_f = (vf * vf - vs * vs) / (2 * a)
        dt = np.array([vs / a, (self.slow_length_mm - ramp_s) / vs, (vf - vs) / a,
                       (self.fast_length_mm - 2 * ramp_f) / vf, (vf - vs) / a,
                       (self.slow_length_mm - ramp_s) / vs, vs / a])
        v0 = np.array([0.0, vs, vs, vf, vf, vs, vs])
        acc = np.array([a, 0.0, a, 0.0, -a, 0.0, -a])
        kind = np.array([PHASE_ACCEL, PHASE_CRUISE, PHASE_ACCEL, PHASE_CRUISE, PHASE_DECEL,
                         PHASE_CRUISE, PHASE_DECEL], dtype=np.int8)
        return dt, v0, acc, kind

    def phase_times_s(self) -> FloatArray:
        """Start of each phase and the end of the line, s, shape (8,)."""
        dt = self.phases()[0]
        return np.concatenate(([0.0], np.cumsum(dt)))

    def print_speed_mm_s(self, t_s: npt.ArrayLike) -> FloatArray:
        """Print speed at times ``t_s`` (0 before and after the line), mm/s."""
        dt, v0, acc, _ = self.phases()
        t = np.asarray(t_s, dtype=np.float64)
        knots = self.phase_times_s()
        speeds = np.concatenate((v0, [v0[-1] + acc[-1] * dt[-1]]))
        return np.interp(t, knots, speeds, left=0.0, right=0.0)

    def position_mm(self, t_s: npt.ArrayLike) -> FloatArray:
        """Distance along the line at times ``t_s``, mm (0 … total length)."""
        dt, v0, acc, _ = self.phases()
        knots = self.phase_times_s()
        t = np.clip(np.asarray(t_s, dtype=np.float64), 0.0, knots[-1])
        i = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, dt.size - 1)
        start = np.concatenate(([0.0], np.cumsum(v0 * dt + 0.5 * acc * dt * dt)))
        tau = t - knots[i]
        return np.asarray(start[i] + v0[i] * tau + 0.5 * acc[i] * tau * tau)

    def feed(self, *, rest_s: float = 0.5) -> CommandedFeed:
        """The commanded filament feed of the line (no advance), one move per phase.

        Parameters
        ----------
        rest_s
            Standstill appended after the line, s (the column relaxes; ≥ 0).

        Returns
        -------
        CommandedFeed
            Piecewise-linear filament speed ``v0 = A_bead/A_fil · v_print``.
        """
        dt, v0, acc, kind = self.phases()
        if rest_s > 0.0:
            dt = np.append(dt, rest_s)
            v0 = np.append(v0, 0.0)
            acc = np.append(acc, 0.0)
            kind = np.append(kind, PHASE_CRUISE).astype(np.int8)
        coef = np.zeros((dt.size, 4))
        coef[:, 0] = self.e_per_mm * v0
        coef[:, 1] = self.e_per_mm * acc
        return _feed(dt, coef, kind)


def _feed(dt: FloatArray, coef: FloatArray, kind: npt.NDArray[np.int8]) -> CommandedFeed:
    seg = dt * (coef[:, 0] + dt * (coef[:, 1] / 2 + dt * (coef[:, 2] / 3 + dt * coef[:, 3] / 4)))
    t0 = np.concatenate(([0.0], np.cumsum(dt)[:-1]))
    e0 = np.concatenate(([0.0], np.cumsum(seg)[:-1]))
    n = dt.size
    return CommandedFeed(t0_s=t0, dt_s=dt, coef=coef, e0_mm=e0,
                         move=np.arange(n, dtype=np.int64), gap=np.zeros(n, dtype=bool),
                         phase=kind, move_t0_s=t0, move_t1_s=t0 + dt, move_de_mm=seg)


def advance_feed(feed: CommandedFeed, k_la_s: float) -> CommandedFeed:
    """Linear advance ``v_in = v0 + K_LA·dv0/dt`` [001 Eq. 11] of a piecewise-linear feed.

    Parameters
    ----------
    feed
        Piecewise-linear feed (``coef[:, 2:] == 0``).
    k_la_s
        Advance factor ``K_LA``, s (≥ 0).

    Returns
    -------
    CommandedFeed
        Same segments; the speed of each is raised by ``K_LA`` times its slope.
    """
    if not (k_la_s >= 0.0 and math.isfinite(k_la_s)):
        raise DataError("K_LA must be >= 0", field="k_la_s", value=k_la_s, allowed=">= 0 s")
    if np.any(feed.coef[:, 2:] != 0.0):
        raise DataError("linear advance needs a piecewise-linear feed", field="coef",
                        value="cubic terms", allowed="c2 = c3 = 0")
    coef = feed.coef.copy()
    coef[:, 0] += k_la_s * coef[:, 1]
    return _feed(feed.dt_s.copy(), coef, feed.phase.copy())


def discrete_advance_feed(line: KFactorLine, k_la_s: float, step_s: float, *,
                          rest_s: float = 0.5) -> CommandedFeed:
    """The line with the discrete advance of [001 Eq. 13] on steps of ``step_s``.

    ``ΔD0_n`` is the filament the line asks for in step ``n``; the firmware moves
    ``ΔD_n = K_LA·(ΔD0_n/Δt − ΔD0_(n−1)/Δt) + ΔD0_n`` at constant speed within the step.

    Parameters
    ----------
    line
        The test line.
    k_la_s
        ``K_LA``, s (≥ 0).
    step_s
        Step ``Δt``, s (> 0).
    rest_s
        Standstill after the line, s.

    Returns
    -------
    CommandedFeed
        Piecewise-constant speed, one segment per step.
    """
    if not (step_s > 0.0 and math.isfinite(step_s)):
        raise DataError("the advance step must be > 0", field="step_s", value=step_s,
                        allowed="> 0 s")
    if not (k_la_s >= 0.0 and math.isfinite(k_la_s)):
        raise DataError("K_LA must be >= 0", field="k_la_s", value=k_la_s, allowed=">= 0 s")
    t_end = float(line.phase_times_s()[-1]) + rest_s
    n = int(math.ceil(t_end / step_s))
    edges = step_s * np.arange(n + 1)
    d0 = line.e_per_mm * np.diff(line.position_mm(edges))      # ΔD0_n, mm
    rate = d0 / step_s
    prev = np.concatenate(([0.0], rate[:-1]))
    d = k_la_s * (rate - prev) + d0                            # [001 Eq. 13]
    coef = np.zeros((n, 4))
    coef[:, 0] = d / step_s
    return _feed(np.full(n, step_s), coef, np.full(n, PHASE_CRUISE, dtype=np.int8))


@dataclass(frozen=True)
class LineResponse:
    """Output of the extruder along a feed, sampled.

    Attributes
    ----------
    t_s
        Sample times, s.
    v_cmd_mm_s
        Commanded filament speed without advance ``v0``, mm/s.
    v_out_mm_s
        Output ``v*_out = Q_out/A_fil``, mm/s [001 Eq. 5].
    """

    t_s: FloatArray
    v_cmd_mm_s: FloatArray
    v_out_mm_s: FloatArray


def respond(feed: CommandedFeed, lag_s: float, *, nominal: FloatArray | None = None,
            dt_s: float = 0.0005, compliance_mm_per_n: float = 0.01) -> LineResponse:
    """Integrate the lag with no backflow [001 Eqs. 10, 15, Fig. 8] over a feed.

    Uses :func:`flowtwin.dynamics.integrate` without slip (as [001], which tunes flow and
    slip beforehand); the compliance then only scales the force, not the flow.

    Parameters
    ----------
    feed
        Commanded feed (with or without advance).
    lag_s
        Lag factor ``K``, s (> 0).
    nominal
        Commanded speed without advance at the sample times (default: the feed's own).
    dt_s
        Sample interval, s.
    compliance_mm_per_n
        Column compliance, mm/N (force scale only).

    Returns
    -------
    LineResponse
    """
    params = ExtrusionParams.build(feed.n_moves, lag_k_s=lag_s,
                                   compliance_mm_per_n=compliance_mm_per_n,
                                   filament_diameter_mm=1.75)
    res = integrate(feed, params, series_dt_s=dt_s)
    series = res.series
    assert series is not None  # asked for
    t = np.asarray(series["t_s"], dtype=np.float64)
    v_out = np.asarray(series["q_out_mm3_s"], dtype=np.float64) / params.filament_area_mm2
    v_cmd = np.asarray(series["v_cmd_mm_s"], dtype=np.float64) if nominal is None else nominal
    return LineResponse(t, v_cmd, v_out)


def linear_lag_response(feed: CommandedFeed, lag_s: float, t_s: npt.ArrayLike) -> FloatArray:
    """Uncorrected lag ``v_in = K·dv*/dt + v*`` [001 Eq. 10] (no no-backflow clamp), closed form.

    On each segment ``v_in = c0 + c1·τ`` the compression is the exact lag step
    :func:`flowtwin.physics.lag.lag_linear` (backflow allowed); the output is ``v* = x/K``,
    negative when the column is pulled back [001 Fig. 7].

    Parameters
    ----------
    feed
        Piecewise-linear feed.
    lag_s
        ``K``, s (> 0).
    t_s
        Sample times, s (within the feed).

    Returns
    -------
    ndarray
        ``v*_out``, mm/s, shape of ``t_s``.
    """
    if not lag_s > 0.0:
        raise DataError("the lag factor must be > 0", field="lag_s", value=lag_s,
                        allowed="> 0 s")
    k = lag_s
    c0, c1 = feed.coef[:, 0].tolist(), feed.coef[:, 1].tolist()
    dt = feed.dt_s.tolist()
    x_start = [0.0] * feed.n_segments
    x = 0.0
    for i in range(feed.n_segments):
        x_start[i] = x
        x = lag_linear(x, c0[i], c1[i], dt[i], k)[0]
    t = np.asarray(t_s, dtype=np.float64)
    seg = np.clip(np.searchsorted(feed.t0_s, t, side="right") - 1, 0, feed.n_segments - 1)
    tau = np.maximum(t - feed.t0_s[seg], 0.0)
    xs = [lag_linear(x_start[i], c0[i], c1[i], ts, k)[0]
          for i, ts in zip(seg.tolist(), tau.ravel().tolist(), strict=True)]
    return np.asarray(xs, dtype=np.float64).reshape(t.shape) / k
