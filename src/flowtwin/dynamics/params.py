"""Per-move physical parameters of the extrusion dynamics, validated.

The integrator takes plain numbers: the lag factor ``K`` (s) [001 Eq. 5], the column
compliance ``k`` (mm/N) [001 Eq. 2, 002], the slip law [000 Eqs. 6, 8] and the roller's
maximum feed force [000 Figs. 4–8]. How they follow from temperature, viscosity, nozzle and
drive geometry is the physics layer's business (``flowtwin.physics``); here each may be
given as

* a float (the same for every move),
* an array of shape ``(n_moves,)`` computed upstream, or
* a callable of the nozzle temperature per move (°C, shape ``(n_moves,)``) returning such
  an array — e.g. ``K(T)`` from the viscosity law [002] — evaluated on
  :func:`flowtwin.dynamics.thermal.move_temperatures`.

Parameters are constant within a move; a stop between moves uses the parameters of the
move before it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError

__all__ = ["ExtrusionParams", "ParamSpec", "resolve_per_move"]

#: A parameter: scalar, per-move array, or function of the per-move temperature (°C).
ParamSpec = float | npt.ArrayLike | Callable[[npt.NDArray[np.float64]], npt.ArrayLike]


def resolve_per_move(value: ParamSpec, n_moves: int, *, name: str,
                     temperature_c: npt.NDArray[np.float64] | None = None,
                     lo: float = -math.inf, hi: float = math.inf,
                     lo_open: bool = False, allow_inf: bool = False) -> npt.NDArray[np.float64]:
    """Turn a parameter spec into a validated float64 array of shape ``(n_moves,)``.

    A float becomes a read-only view of that one value with stride 0
    (``np.broadcast_to``): every move sees it, no memory per move is written.

    Parameters
    ----------
    value
        Float, array ``(n_moves,)`` or callable of the temperature array.
    n_moves
        Number of moves.
    name
        Parameter name for error messages.
    temperature_c
        Nozzle temperature per move, °C, shape ``(n_moves,)``; required for callables.
    lo, hi
        Allowed range (``lo < v`` if ``lo_open`` else ``lo <= v``; ``v <= hi``).
    allow_inf
        Accept ``+inf`` (e.g. "no grinding limit").

    Raises
    ------
    ProfileError
        Wrong shape, NaN, infinity (unless allowed) or a value out of range; the message
        names the parameter, the first bad move and the allowed range.
    """
    if callable(value):
        if temperature_c is None:
            raise ProfileError("a temperature-dependent parameter needs the temperature per "
                               "move", field=name, allowed="pass temperature_c")
        arr = np.asarray(value(np.asarray(temperature_c, dtype=np.float64)), dtype=np.float64)
    else:
        arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        # one value for every move: check it once (a bad one is reported at move 0)
        _check_range(arr.reshape(1), name=name, lo=lo, hi=hi, lo_open=lo_open,
                     allow_inf=allow_inf)
        # a read-only view with stride 0 (no memory per move: on a print of 2 M moves each
        # materialised constant was 17 MB of fresh pages); the integrator passes its one
        # value to the kernel
        return np.broadcast_to(np.float64(arr), (n_moves,))
    if arr.shape != (n_moves,):
        raise ProfileError("parameter has the wrong shape", field=name, value=arr.shape,
                           allowed=f"a number or shape ({n_moves},)")
    _check_range(arr, name=name, lo=lo, hi=hi, lo_open=lo_open, allow_inf=allow_inf)
    return arr


def _check_range(arr: npt.NDArray[np.float64], *, name: str, lo: float, hi: float,
                 lo_open: bool, allow_inf: bool) -> None:
    ok = ~np.isnan(arr)
    ok &= np.isfinite(arr) | (allow_inf & (arr == math.inf))
    ok &= (arr > lo) if lo_open else (arr >= lo)
    ok &= arr <= hi
    if not np.all(ok):
        i = int(np.flatnonzero(~ok)[0])
        rng = f"{lo!r} {'<' if lo_open else '<='} {name} <= {hi!r}"
        raise ProfileError(f"parameter out of range at move {i}", field=name,
                           value=float(arr[i]), allowed=rng)


@dataclass(frozen=True, slots=True)
class ExtrusionParams:
    """Per-move parameters of the state equation (docs/spec.md §3.4), shape ``(n_moves,)``.

    Attributes
    ----------
    lag_k_s
        Lag factor ``K``, s, ``> 0`` [001 Eq. 5]: ``Δl = K · Q_out / A_fil``.
    compliance_mm_per_n
        Column compliance ``k``, mm/N, ``> 0`` [001 Eq. 2]: ``Δl = k · F_f``.
    slip_offset
        ``k_p`` of [000 Eq. 6], fraction, ``-1 < k_p < 1``.
    slip_gradient_per_n
        ``a`` of [000 Eq. 8] (or the constant ``s' = k_s/F_p² + k_∞`` of Eq. 6), 1/N, ``>= 0``.
    slip_velocity_gain_per_n
        ``b`` of [000 Eq. 8], 1/N, ``>= 0`` (0: no velocity dependence).
    slip_velocity_decay_s_per_mm
        ``c`` of [000 Eq. 8], s/mm, ``>= 0``.
    max_feed_force_n
        Feed force at which the roller grinds [000 §4], N, ``> 0`` or ``inf`` (never).
    filament_area_mm2
        Filament cross-section ``A_fil``, mm².
    grind_release_fraction
        Hysteresis of grinding: feeding resumes when the force falls below
        ``(1 - fraction) · max_feed_force_n``; ``0 <= fraction < 1``.
    """

    lag_k_s: npt.NDArray[np.float64]
    compliance_mm_per_n: npt.NDArray[np.float64]
    slip_offset: npt.NDArray[np.float64]
    slip_gradient_per_n: npt.NDArray[np.float64]
    slip_velocity_gain_per_n: npt.NDArray[np.float64]
    slip_velocity_decay_s_per_mm: npt.NDArray[np.float64]
    max_feed_force_n: npt.NDArray[np.float64]
    filament_area_mm2: float
    grind_release_fraction: float = 0.2

    def __post_init__(self) -> None:
        n = self.lag_k_s.shape
        for name in ("compliance_mm_per_n", "slip_offset", "slip_gradient_per_n",
                     "slip_velocity_gain_per_n", "slip_velocity_decay_s_per_mm",
                     "max_feed_force_n"):
            arr = getattr(self, name)
            if arr.shape != n or arr.dtype != np.float64:
                raise ProfileError("per-move parameter arrays must be float64 of one shape",
                                   field=name, value=(arr.shape, str(arr.dtype)),
                                   allowed=f"float64 {n}")
        if len(n) != 1 or self.lag_k_s.dtype != np.float64:
            raise ProfileError("per-move parameters must be 1-D float64", field="lag_k_s",
                               value=(n, str(self.lag_k_s.dtype)), allowed="float64 (n_moves,)")

    @property
    def n_moves(self) -> int:
        """Number of moves the parameters are given for."""
        return int(self.lag_k_s.shape[0])

    @classmethod
    def build(cls, n_moves: int, *, lag_k_s: ParamSpec, compliance_mm_per_n: ParamSpec,
              filament_diameter_mm: float = 1.75, slip_offset: ParamSpec = 0.0,
              slip_gradient_per_n: ParamSpec = 0.0, slip_velocity_gain_per_n: ParamSpec = 0.0,
              slip_velocity_decay_s_per_mm: ParamSpec = 0.0,
              max_feed_force_n: ParamSpec = math.inf, grind_release_fraction: float = 0.2,
              temperature_c: npt.NDArray[np.float64] | None = None) -> ExtrusionParams:
        """Validate and broadcast parameters to ``n_moves`` moves.

        Parameters
        ----------
        n_moves
            Number of moves (``>= 1``).
        lag_k_s, compliance_mm_per_n, slip_offset, slip_gradient_per_n,
        slip_velocity_gain_per_n, slip_velocity_decay_s_per_mm, max_feed_force_n
            See the class attributes; each a float, an ``(n_moves,)`` array or a callable
            of the temperature per move.
        filament_diameter_mm
            Filament diameter, mm (``A_fil = π d²/4``).
        grind_release_fraction
            Grinding hysteresis (class attributes).
        temperature_c
            Nozzle temperature per move, °C, for callable parameters.

        Raises
        ------
        ProfileError
            A value out of its range (message names the parameter and move).
        """
        if n_moves < 1:
            raise ProfileError("need at least one move", field="n_moves", value=n_moves,
                               allowed=">= 1")
        if not (0.0 < filament_diameter_mm < 10.0):
            raise ProfileError("filament diameter out of range", field="filament_diameter_mm",
                               value=filament_diameter_mm, allowed="0 < d < 10 mm")
        if not (0.0 <= grind_release_fraction < 1.0):
            raise ProfileError("grinding hysteresis out of range",
                               field="grind_release_fraction", value=grind_release_fraction,
                               allowed="0 <= fraction < 1")
        t_c = temperature_c
        return cls(
            lag_k_s=resolve_per_move(lag_k_s, n_moves, name="lag_k_s", lo=0.0, lo_open=True,
                                     temperature_c=t_c),
            compliance_mm_per_n=resolve_per_move(compliance_mm_per_n, n_moves,
                                                 name="compliance_mm_per_n", lo=0.0,
                                                 lo_open=True, temperature_c=t_c),
            slip_offset=resolve_per_move(slip_offset, n_moves, name="slip_offset", lo=-1.0,
                                         hi=0.999, lo_open=True, temperature_c=t_c),
            slip_gradient_per_n=resolve_per_move(slip_gradient_per_n, n_moves,
                                                 name="slip_gradient_per_n", lo=0.0,
                                                 temperature_c=t_c),
            slip_velocity_gain_per_n=resolve_per_move(slip_velocity_gain_per_n, n_moves,
                                                      name="slip_velocity_gain_per_n",
                                                      lo=0.0, temperature_c=t_c),
            slip_velocity_decay_s_per_mm=resolve_per_move(
                slip_velocity_decay_s_per_mm, n_moves, name="slip_velocity_decay_s_per_mm",
                lo=0.0, temperature_c=t_c),
            max_feed_force_n=resolve_per_move(max_feed_force_n, n_moves,
                                              name="max_feed_force_n", lo=0.0, lo_open=True,
                                              allow_inf=True, temperature_c=t_c),
            filament_area_mm2=math.pi * filament_diameter_mm ** 2 / 4.0,
            grind_release_fraction=float(grind_release_fraction),
        )
