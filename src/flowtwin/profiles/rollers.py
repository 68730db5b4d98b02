"""Drive rollers of [000] (Nienhaus, Spiehl, Dörsam 2021): geometry, slip parameters, fits.

The data file ``flowtwin/data/rollers.toml`` keeps the paper's numbers in the paper's units,
named by unit (docs/spec.md §2):

* Table 2 geometry: outer diameter, chordal pitch, flank angle, each with its tolerance;
* Table 3: ``F_p,min`` as tabulated (``fp_min_tabulated_N``), ``k_s`` in %·N
  (``k_s_pct_N``), ``k_∞`` in %/N (``k_inf_pct_per_N``), and ``a, b`` (%/N), ``c``
  (s/mm) of Eq. 8, with their published uncertainties;
* the 2nd-order fits of the maximum feed force over the pinch force, Figs. 4–8.

:class:`Roller` converts to the internal units on access (slip as a fraction, forces in N):

================== =================== =====================================
property           unit                from
================== =================== =====================================
``k_s_n``          fraction·N          ``k_s_pct_N / 100``
``k_inf_per_n``    fraction/N          ``k_inf_pct_per_N / 100``
``a_per_n``        fraction/N          ``a_pct_per_N / 100``
``b_per_n``        fraction/N          ``b_pct_per_N / 100``
``c_s_per_mm``     s/mm                unchanged (``v_fil`` in mm/s)
``fp_min_eq9_n``   N                   ``sqrt(k_s/(0.1·k_∞))`` [000 Eq. 9]
================== =================== =====================================

These names are a stable interface for :mod:`flowtwin.physics`.

Slip model [000 Eq. 6]: ``s = k_p + (k_s/F_p² + k_∞)·F_f``; velocity law at
``F_p`` = 80–130 N [000 Eq. 8]: ``s' = a + b·exp(−c·v_fil)``.

Data check surfaced, not hidden (docs/spec.md §3.1): Table 3 gives ``F_p,min = 77 N`` for roller
#3, but Eq. 9 with its own ``k_s = 96.0 %·N`` and ``k_∞ = 0.32 %/N`` gives 54.8 N; every
other row agrees with Eq. 9 within 2 %. :meth:`Roller.fp_min_discrepancy` reports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pydantic import Field, model_validator

from flowtwin.errors import ProfileError
from flowtwin.profiles.base import ProfileModel

__all__ = [
    "FP_MIN_REL_TOLERANCE",
    "FpMinCheck",
    "MaxFeedForceFit",
    "Roller",
    "RollerTable",
]

#: Relative agreement between tabulated F_p,min and Eq. 9 regarded as consistent. Table 3
#: rounds F_p,min to whole newtons and k_∞ to 0.01 %/N (3–5 % relative for k_∞ ≈ 0.2–0.6,
#: i.e. 1.5–2.5 % on its square root); 2 % is the agreement docs/spec.md §3.1 states for rows ≠ #3.
FP_MIN_REL_TOLERANCE = 0.02


class MaxFeedForceFit(ProfileModel):
    """Second-order fit ``F_f,max = c2·F_p² + c1·F_p + c0`` of the maximum feed force.

    "General 2nd order polynomial fit" over all feed velocities, [000 Figs. 4–8]; valid
    over the pinch forces of the test series (10–150 N in 10 N steps, [000 §3]).
    """

    c2_per_N: float = Field(ge=-1.0, le=1.0, description="Coefficient of F_p², 1/N.")
    c1: float = Field(ge=-100.0, le=100.0, description="Coefficient of F_p (dimensionless).")
    c0_N: float = Field(ge=-1000.0, le=1000.0, description="Constant term, N.")
    fp_min_valid_N: float = Field(gt=0.0, le=1000.0,
                                  description="Lowest pinch force the fit is valid for, N.")
    fp_max_valid_N: float = Field(gt=0.0, le=1000.0,
                                  description="Highest pinch force the fit is valid for, N.")
    figure: str = Field("", max_length=200, description="Where the fit is published.")

    @model_validator(mode="after")
    def _range(self) -> MaxFeedForceFit:
        if self.fp_min_valid_N >= self.fp_max_valid_N:
            raise ValueError(f"fp_min_valid_N ({self.fp_min_valid_N}) must be below "
                             f"fp_max_valid_N ({self.fp_max_valid_N})")
        return self

    def max_feed_force_n(self, pinch_force_n: float) -> float:
        """Maximum feed force before the drive fails, N [000 Figs. 4–8].

        Parameters
        ----------
        pinch_force_n
            Pinch force F_p between the rollers, N; must lie in the fit's validity range.

        Returns
        -------
        float
            ``c2·F_p² + c1·F_p + c0``, N.

        Raises
        ------
        ProfileError
            If ``pinch_force_n`` is outside ``[fp_min_valid_N, fp_max_valid_N]``
            (the fit is not extrapolated).
        """
        if not self.fp_min_valid_N <= pinch_force_n <= self.fp_max_valid_N:
            raise ProfileError(
                f"pinch force outside the range of the maximum-feed-force fit {self.figure}",
                field="pinch_force_n", value=pinch_force_n,
                allowed=f"{self.fp_min_valid_N:g} <= pinch_force_n <= {self.fp_max_valid_N:g}")
        fp = pinch_force_n
        return self.c2_per_N * fp * fp + self.c1 * fp + self.c0_N


@dataclass(frozen=True, slots=True)
class FpMinCheck:
    """Tabulated minimal pinch force against Eq. 9 recomputed from k_s and k_∞.

    Attributes
    ----------
    tabulated_n
        ``F_p,min`` as printed in [000 Table 3], N.
    eq9_n
        ``sqrt(k_s/(0.1·k_∞))`` [000 Eq. 9] from the tabulated k_s and k_∞, N.
    relative_difference
        ``(tabulated − eq9)/eq9``.
    consistent
        ``|relative_difference| <= FP_MIN_REL_TOLERANCE``.
    note
        The data file's explanation where the row is known to disagree (roller #3).
    """

    tabulated_n: float
    eq9_n: float
    relative_difference: float
    consistent: bool
    note: str | None


class Roller(ProfileModel):
    """One driving roller: Table 2 geometry, Table 3 slip parameters, max-feed-force fit.

    ``number`` is the row of [000] (1–7), or absent for a custom roller defined in a drive
    profile. Paper-unit fields are named by unit; internal-unit properties are listed in
    the module docstring.
    """

    number: int | None = Field(None, ge=1, le=7, description="Roller number in [000] "
                                                             "Tables 2–3 (absent: custom).")
    label: str = Field(min_length=1, max_length=200, description="Description (Table 2).")
    tooth_form: Literal["straight_knurl", "diamond_knurl", "elliptical_groove", "plain",
                        "gear"] = Field(description="Tooth geometry family.")
    teeth: int | None = Field(None, ge=1, le=1000, description="Number of teeth, if known.")
    outer_diameter_mm: float = Field(gt=0.0, le=100.0, description="Outer diameter, mm.")
    outer_diameter_tol_mm: float | None = Field(None, ge=0.0, le=10.0,
                                                description="Tolerance (±), mm.")
    chordal_pitch_mm: float | None = Field(None, gt=0.0, le=20.0,
                                           description="Chordal pitch (tooth spacing), mm.")
    chordal_pitch_tol_mm: float | None = Field(None, ge=0.0, le=10.0,
                                               description="Tolerance (±), mm.")
    flank_angle_deg: float | None = Field(None, gt=0.0, lt=180.0,
                                          description="Angle between the flanks, degrees.")
    flank_angle_tol_deg: float | None = Field(None, ge=0.0, le=90.0,
                                              description="Tolerance (±), degrees.")
    tooth_depth_mm: float | None = Field(None, gt=0.0, le=10.0,
                                         description="Tooth / groove depth, mm.")
    roughness_rz_um: float | None = Field(None, ge=0.0, le=1000.0,
                                          description="Surface roughness R_z, µm.")
    roughness_rz_tol_um: float | None = Field(None, ge=0.0, le=1000.0,
                                              description="Tolerance (±), µm.")
    fp_min_tabulated_N: float | None = Field(None, gt=0.0, le=1000.0,
                                             description="F_p,min as printed in Table 3, N.")
    fp_min_note: str | None = Field(None, max_length=2000,
                                    description="Known problem with the tabulated F_p,min.")
    k_s_pct_N: float = Field(gt=0.0, le=1e5, description="k_s of Eq. 6, %·N.")
    k_s_pct_N_err: float | None = Field(None, ge=0.0, le=1e5, description="± of k_s, %·N.")
    k_inf_pct_per_N: float = Field(gt=0.0, le=100.0, description="k_∞ of Eq. 6, %/N.")
    k_inf_pct_per_N_err: float | None = Field(None, ge=0.0, le=100.0,
                                              description="± of k_∞, %/N.")
    velocity_dependent: bool = Field(description="True if Eq. 8 has a velocity term "
                                                 "(False for rollers #6, #7: s' = a).")
    a_pct_per_N: float | None = Field(None, gt=0.0, le=100.0,
                                      description="a of Eq. 8, %/N (F_p 80–130 N).")
    a_pct_per_N_err: float | None = Field(None, ge=0.0, le=100.0, description="± of a, %/N.")
    b_pct_per_N: float | None = Field(None, gt=0.0, le=100.0, description="b of Eq. 8, %/N.")
    b_pct_per_N_err: float | None = Field(None, ge=0.0, le=100.0, description="± of b, %/N.")
    c_s_per_mm: float | None = Field(None, gt=0.0, le=100.0,
                                     description="c of Eq. 8, s/mm (v_fil in mm/s).")
    c_s_per_mm_err: float | None = Field(None, ge=0.0, le=100.0, description="± of c, s/mm.")
    velocity_law_note: str | None = Field(None, max_length=2000,
                                          description="How Table 3 states the velocity "
                                                      "law when it has no finite b, c.")
    max_feed_force_fit: MaxFeedForceFit | None = Field(None, description="Figs. 4–8 fit.")
    source: str = Field("", max_length=2000, description="Citation of the values.")

    @model_validator(mode="after")
    def _velocity_law(self) -> Roller:
        if self.velocity_dependent:
            missing = [k for k in ("a_pct_per_N", "b_pct_per_N", "c_s_per_mm")
                       if getattr(self, k) is None]
            if missing:
                raise ValueError("velocity_dependent = true needs a_pct_per_N, b_pct_per_N "
                                 f"and c_s_per_mm; missing: {', '.join(missing)}")
        elif self.b_pct_per_N is not None or self.c_s_per_mm is not None:
            raise ValueError("velocity_dependent = false means s' = a [000 Eq. 8 with "
                             "b·exp(-c·v) -> 0]: leave b_pct_per_N and c_s_per_mm out")
        return self

    # --- internal units -------------------------------------------------------------
    @property
    def name(self) -> str:
        """Library name: ``roller-<number>`` or ``custom-roller``."""
        return f"roller-{self.number}" if self.number is not None else "custom-roller"

    @property
    def outer_radius_mm(self) -> float:
        """Outer radius r of [000 Eq. 1], mm."""
        return self.outer_diameter_mm / 2.0

    @property
    def k_s_n(self) -> float:
        """k_s in fraction·N (``k_s_pct_N / 100``); ``k_s/F_p²`` is then fraction/N."""
        return self.k_s_pct_N / 100.0

    @property
    def k_inf_per_n(self) -> float:
        """k_∞ in fraction/N (``k_inf_pct_per_N / 100``)."""
        return self.k_inf_pct_per_N / 100.0

    @property
    def a_per_n(self) -> float | None:
        """a of Eq. 8 in fraction/N, or None if not given."""
        return None if self.a_pct_per_N is None else self.a_pct_per_N / 100.0

    @property
    def b_per_n(self) -> float | None:
        """b of Eq. 8 in fraction/N; None when there is no velocity term."""
        return None if self.b_pct_per_N is None else self.b_pct_per_N / 100.0

    @property
    def fp_min_eq9_n(self) -> float:
        """Minimal pinch force from [000 Eq. 9], ``sqrt(k_s/(0.1·k_∞))``, N.

        The ratio ``k_s/k_∞`` has unit N² in any consistent slip unit (% or fraction).
        """
        return math.sqrt(self.k_s_pct_N / (0.1 * self.k_inf_pct_per_N))

    def fp_min_discrepancy(self) -> FpMinCheck | None:
        """Compare the tabulated F_p,min with Eq. 9 (None if nothing is tabulated).

        Returns
        -------
        FpMinCheck or None
            For roller #3 of [000] this reports 77 N tabulated against 54.8 N from Eq. 9
            (``consistent`` is False); the other six rows agree within 2 %.
        """
        if self.fp_min_tabulated_N is None:
            return None
        eq9 = self.fp_min_eq9_n
        rel = (self.fp_min_tabulated_N - eq9) / eq9
        return FpMinCheck(tabulated_n=self.fp_min_tabulated_N, eq9_n=eq9,
                          relative_difference=rel,
                          consistent=abs(rel) <= FP_MIN_REL_TOLERANCE,
                          note=self.fp_min_note)


class RollerTable(ProfileModel):
    """The contents of ``rollers.toml``: the seven rollers of [000] and their provenance."""

    source: str = Field(min_length=1, max_length=2000, description="Citation.")
    notes: str = Field("", max_length=5000, description="Transcription notes.")
    roller: tuple[Roller, ...] = Field(min_length=1, strict=False,
                                       description="One entry per roller ([[roller]]).")

    @model_validator(mode="after")
    def _unique_numbers(self) -> RollerTable:
        numbers = [r.number for r in self.roller]
        if any(n is None for n in numbers):
            raise ValueError("every roller of the table needs a number (1-7)")
        if len(set(numbers)) != len(numbers):
            raise ValueError(f"roller numbers must be unique; got {numbers}")
        return self
