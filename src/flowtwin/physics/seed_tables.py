"""Numbers transcribed from the seed papers, in the papers' own units (read-only).

Used by :mod:`flowtwin.physics.defaults` and by the tests that check the physics functions
against their sources. Parameters keep the paper's units and say so in their names
(``k_s_pct_n`` in %·N, ``k_inf_pct_per_n`` in %/N; docs/spec.md §2); divide by 100 for fractions.

Table 3 of [000] prints the pinch-force law as ``k_s/F_p`` and the unit of ``k_∞`` as
"%N"; Eq. 6 and the text give ``k_s/F_p²`` and %/N, which is what the numbers satisfy
(Eq. 9 reproduces the ``F_p,min`` column within 2 % except roller #3, docs/spec.md §3.1).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

__all__ = ["ROLLERS", "TRONVOLL_TABLE_II", "RollerData", "TronvollLayer"]


@dataclass(frozen=True)
class RollerData:
    """One driving roller of [000] (Tables 2–3, Figs. 4–8).

    Attributes
    ----------
    number
        Roller number ``#1 … #7``.
    description
        Roller type [000 Table 2].
    outer_diameter_mm
        Outer diameter, mm [000 Table 2].
    f_p_min_n
        Minimal pinch force as printed in [000 Table 3], N.
    k_s_pct_n
        ``k_s``, %·N [000 Table 3].
    k_inf_pct_per_n
        ``k_∞``, %/N [000 Table 3].
    a_pct_per_n, b_pct_per_n
        Velocity-law ``a``, ``b``, %/N [000 Table 3]; rollers #6 and #7 (``→ ∞``/``→ 0``
        rows: no velocity dependence) have ``b = 0``.
    c_s_per_mm
        Velocity-law ``c``, s/mm [000 Table 3] (0 where ``b = 0``).
    max_feed_force_coeffs
        ``(c0, c1, c2)`` of ``F_f,max = c0 + c1·F_p + c2·F_p²``, N [000 Figs. 4–8].
    """

    number: int
    description: str
    outer_diameter_mm: float
    f_p_min_n: float
    k_s_pct_n: float
    k_inf_pct_per_n: float
    a_pct_per_n: float
    b_pct_per_n: float
    c_s_per_mm: float
    max_feed_force_coeffs: tuple[float, float, float]


#: Rollers #1–#7 of [000], keyed by number.
ROLLERS: MappingProxyType[int, RollerData] = MappingProxyType({
    1: RollerData(1, "Straight knurl (RAA 10-105)", 10.90, 129.0, 356.8, 0.22,
                  0.14, 0.16, 0.08, (6.52, 1.27, -3.73e-3)),
    2: RollerData(2, "Diamond knurl (RGE 08-90)", 8.64, 112.0, 788.5, 0.63,
                  0.47, 0.37, 0.32, (0.5, 1.06, -2.78e-3)),
    3: RollerData(3, "Hobb-Goblin, 35 teeth", 7.98, 77.0, 96.0, 0.32,
                  0.24, 0.18, 0.32, (7.5, 1.52, -6.03e-3)),
    4: RollerData(4, "Plain roller", 8.02, 44.0, 404.8, 2.06,
                  1.24, 2.07, 0.73, (3.7, 3.46e-1, -2.80e-5)),
    5: RollerData(5, "Straight knurl (RAA 06-90)", 12.20, 100.0, 286.8, 0.29,
                  0.23, 0.37, 0.83, (-2.1, 1.31, -4.64e-3)),
    6: RollerData(6, "Straight knurl (RAA 08-90), 16 mm", 16.20, 129.0, 627.4, 0.38,
                  0.43, 0.0, 0.0, (-8.7, 1.37, -4.60e-3)),
    7: RollerData(7, "Straight knurl (RAA 08-90), 20 mm", 20.03, 172.0, 643.0, 0.22,
                  0.29, 0.0, 0.0, (-5.2, 1.72, -7.86e-3)),
})


@dataclass(frozen=True)
class TronvollLayer:
    """One row of [001 Table II]: ideal ``K_LA`` (s) per layer height."""

    layer_height_mm: float
    k_acceleration_s: float
    k_deceleration_s: float
    k_average_s: float


#: [001 Table II]. The 0.1 mm average is printed "0.9"; the text and Fig. 15 give 0.09 s.
TRONVOLL_TABLE_II: tuple[TronvollLayer, ...] = (
    TronvollLayer(0.1, 0.095, 0.085, 0.09),
    TronvollLayer(0.2, 0.065, 0.055, 0.06),
    TronvollLayer(0.3, 0.05, 0.04, 0.045),
)
