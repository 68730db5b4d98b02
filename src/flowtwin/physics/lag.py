"""The lag factor ``K``: the time constant of the extrusion low-pass [001, 002].

The column shortens by ``Δl = k·F`` [001 Eq. 2]; the force is the melt pressure on the
filament, ``F = ΔP·A_in = R_hyd·Q_out·A_in`` (linear pressure drop); hence
``Δl = k·R_hyd·A_in²·Q_out/A_in``, which is [001 Eq. 5] ``Δl = K·Q_out/A_in`` with

``K = k·R_hyd·A_in²``  (SPEC §3.4).

Mass balance ``v_in − Q_out/A_in = dΔl/dt`` then gives ``v_in = K·dv*_out/dt + v*_out``
[001 Eq. 10], the first-order low-pass ``H(s) = 1/(1 + K·s)`` [001 Eq. 15]. [002] derives the
same filter but prints its time constant as ``const·μ·A_noz·l_hot/E_hot``: its continuity
step is inverted (it should carry the filament area), and the consistent form is
``R_hyd·A_in·l_hot/E_hot`` — about 19× larger for a 0.4 mm nozzle and 1.75 mm filament —
which is ``K`` for a column whose compliance is only its hot part, ``k = l_hot/(E_hot·A_in)``
(a data-check row of ``flowtwin reproduce theory`` shows the difference).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin.physics._checks import as_float_array, require_nonnegative, require_positive

__all__ = ["compression_from_flow_mm", "lag_factor_s", "step_response_fraction"]

FloatArray = npt.NDArray[np.float64]


def lag_factor_s(compliance_mm_per_n: npt.ArrayLike,
                 resistance_mpa_s_per_mm3: npt.ArrayLike,
                 filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Lag factor ``K = k·R_hyd·A_in²`` (SPEC §3.4; [001 Eq. 5]; time constant of [002]).

    Units: mm/N · MPa·s/mm³ · mm⁴ = mm/N · N·s/mm⁵ · mm⁴ = s.

    Parameters
    ----------
    compliance_mm_per_n
        Column compliance ``k``, mm/N (≥ 0), any shape.
    resistance_mpa_s_per_mm3
        Hydraulic resistance ``R_hyd``, MPa·s/mm³ (≥ 0).
    filament_area_mm2
        Filament cross-section ``A_in``, mm² (> 0).

    Returns
    -------
    ndarray
        ``K``, s, broadcast shape.
    """
    area = require_positive("filament_area_mm2", filament_area_mm2)
    return require_nonnegative("compliance_mm_per_n", compliance_mm_per_n) * \
        require_nonnegative("resistance_mpa_s_per_mm3", resistance_mpa_s_per_mm3) * area * area


def compression_from_flow_mm(lag_s: npt.ArrayLike, q_out_mm3_s: npt.ArrayLike,
                             filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Steady column compression at output flow ``Q_out``: ``Δl = K·Q_out/A_in`` [001 Eq. 5].

    Parameters
    ----------
    lag_s
        ``K``, s (≥ 0).
    q_out_mm3_s
        Output volume flow, mm³/s, any shape.
    filament_area_mm2
        Filament cross-section, mm² (> 0).

    Returns
    -------
    ndarray
        ``Δl``, mm, broadcast shape.
    """
    return require_nonnegative("lag_s", lag_s) * as_float_array(q_out_mm3_s) / \
        require_positive("filament_area_mm2", filament_area_mm2)


def step_response_fraction(t_s: npt.ArrayLike, lag_s: npt.ArrayLike) -> FloatArray:
    """Output/input velocity after a feed step at ``t = 0``: ``1 − exp(−t/K)`` [001 Eq. 15].

    The inverse Laplace transform of ``H(s)/s`` with ``H(s) = 1/(1 + K·s)``; 0 for ``t < 0``.

    Parameters
    ----------
    t_s
        Time since the step, s, any shape.
    lag_s
        ``K``, s (> 0).

    Returns
    -------
    ndarray
        Fraction in [0, 1), broadcast shape.
    """
    t = as_float_array(t_s)
    k = require_positive("lag_s", lag_s)
    return np.where(t > 0.0, -np.expm1(-np.maximum(t, 0.0) / k), 0.0)
