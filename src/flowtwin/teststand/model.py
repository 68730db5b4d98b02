"""What the virtual test stand drives and how it measures: drive, instrument, procedure.

The test stand of [000 §3] pushes filament with one driving roller against a friction-based
process-force simulator and records feed force, pinch force and filament velocity. The
virtual stand (docs/spec.md §3.8) replaces the hardware by three plain data objects:

* :class:`DriveUnderTest` — the roller: its slip law, its maximum feed force and how it
  fails (all from :mod:`flowtwin.physics.drive`, parameters from a
  :class:`~flowtwin.profiles.Roller`);
* :class:`Instrument` — the paper's sensors: load cells ±2 N (2σ), optical encoder
  ±0.05 mm/s (2σ), 50 samples/s [000 §3];
* :class:`Procedure` — the measurement algorithm of [000 §3]: ramp the process force at
  4 N/s until the encoder reads below 0.05 mm/s, release at 50 N/s, wait 5 s; pinch forces
  10–150 N in 10 N steps, feed velocities 0.5–1–2–5–10–15 mm/s, three repeats.

Slip laws of the drive under test
---------------------------------
Table 3 of [000] gives two laws fitted to different views of the same data: the pinch-force
law ``s' = k_s/F_p² + k_∞`` [000 Eq. 6] over all feed velocities, and the velocity law
``s' = a + b·exp(−c·v_fil)`` [000 Eq. 8] over pinch forces of 80–130 N. No single
``s'(F_p, v)`` reproduces both exactly (the published numbers are not mutually consistent
for every roller: docs/teststand.md), so the stand offers three laws (:class:`SlipLaw`):

``pinch``
    Eq. 6 only (no velocity dependence). Its Eq. 6 fit returns ``k_s``, ``k_∞``.
``velocity``
    Eq. 8 only (no pinch dependence), meant for ``F_p`` = 80–130 N. Its Eq. 8 fit returns
    ``a``, ``b``, ``c``.
``combined``
    ``s' = k_s/F_p² + k_∞ + b·(exp(−c·v) − ē)``, ``ē`` the mean of ``exp(−c·v)`` over the
    paper's six feed velocities. Over the paper's velocity grid the velocity term averages
    to zero at every pinch force, so the Eq. 6 fit returns ``k_s``, ``k_∞`` exactly in
    expectation, and the Eq. 8 fit returns ``b``, ``c`` with
    ``a' = mean_{80–130 N}(k_s/F_p²) + k_∞ − b·ē`` (equal to Table 3's ``a`` only where
    the two published laws agree).

The slip itself is ``s = k_p + s'·F_f`` [000 Eqs. 6, 8]; ``k_p`` is the stand's offset
(0.63 % in [000 Fig. 9a]). The velocity in Eq. 8 is the nominal feed velocity of the
record (the set points on the abscissa of [000 Fig. 11]).

Failure
-------
The roller fails when the feed force exceeds its maximum feed force, the 2nd-order fit of
[000 Figs. 4–8], optionally scattered per record by a relative standard deviation
``max_force_scatter`` ("maximum fluctuations of 25 N around the global trend line"
[000 §4.1], at trend values of 70–110 N, ≈ 3σ with σ ≈ 8 %). It then eats
into the filament: the filament stops and the feed force drops (Fig. 3, "suddenly
decreases") to ``grind_residual_fraction`` of the maximum (an assumption: [000] does not
give the level) until the process force falls below it again. Independently, the filament
also stops when the linear slip law reaches 100 % slip (``s = 1``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.physics.drive import (
    max_feed_force_n,
    slip_gradient,
    slip_gradient_velocity,
)
from flowtwin.profiles import Roller
from flowtwin.teststand.series import PAPER_PINCH_FORCES_N, PAPER_SPEEDS_MM_S, SlipLaw

__all__ = [
    "PAPER_PINCH_FORCES_N",
    "PAPER_SPEEDS_MM_S",
    "DriveUnderTest",
    "Instrument",
    "Procedure",
    "SlipLaw",
]

FloatArray = npt.NDArray[np.float64]

def _check(name: str, value: float, *, low: float, high: float, low_open: bool = False,
           allowed: str | None = None) -> float:
    ok = math.isfinite(value) and (value > low if low_open else value >= low) and value <= high
    if not ok:
        raise ProfileError(f"test-stand parameter {name} out of range", field=name, value=value,
                           allowed=allowed or (f"{'>' if low_open else '>='} {low:g} and "
                                               f"<= {high:g}"))
    return float(value)


@dataclass(frozen=True)
class DriveUnderTest:
    """The driving roller on the virtual test stand.

    Attributes
    ----------
    roller_id
        Label written to the records (``"1"`` … ``"7"`` for the rollers of [000]).
    k_s_n
        ``k_s`` of [000 Eq. 6], fraction·N (Table 3 value in %·N divided by 100).
    k_inf_per_n
        ``k_∞`` of [000 Eq. 6], fraction/N.
    max_force_coeffs
        ``(c0, c1, c2)`` of the maximum feed force ``c0 + c1·F_p + c2·F_p²``, N
        [000 Figs. 4–8].
    law
        Slip-gradient law (:class:`SlipLaw`).
    a_per_n, b_per_n, c_s_per_mm
        ``a``, ``b`` (fraction/N) and ``c`` (s/mm) of [000 Eq. 8]; ``b = 0`` for rollers
        without velocity dependence. ``a_per_n`` is required for ``law = velocity``.
    k_p
        Slip offset of the stand, fraction [000 Eq. 6, Fig. 9a].
    max_force_scatter
        Relative standard deviation of a per-record random factor on the maximum feed
        force (0: every record fails exactly on the published trend).
    grind_residual_fraction
        Feed force while grinding as a fraction of the maximum feed force, in [0, 1).
    """

    roller_id: str
    k_s_n: float
    k_inf_per_n: float
    max_force_coeffs: tuple[float, float, float]
    law: SlipLaw = SlipLaw.PINCH
    a_per_n: float | None = None
    b_per_n: float = 0.0
    c_s_per_mm: float = 0.0
    k_p: float = 0.0
    max_force_scatter: float = 0.0
    grind_residual_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not self.roller_id or len(self.roller_id) > 64:
            raise ProfileError("roller_id must be 1-64 characters", field="roller_id",
                               value=self.roller_id, allowed="1-64 characters")
        _check("k_s_n", self.k_s_n, low=0.0, high=1e4)
        _check("k_inf_per_n", self.k_inf_per_n, low=0.0, high=1.0)
        _check("b_per_n", self.b_per_n, low=0.0, high=1.0)
        _check("c_s_per_mm", self.c_s_per_mm, low=0.0, high=100.0)
        _check("k_p", self.k_p, low=-0.5, high=0.5)
        _check("max_force_scatter", self.max_force_scatter, low=0.0, high=0.5)
        _check("grind_residual_fraction", self.grind_residual_fraction, low=0.0, high=0.999)
        coeffs = tuple(float(c) for c in self.max_force_coeffs)
        if len(coeffs) != 3 or not all(math.isfinite(c) for c in coeffs):
            raise ProfileError("max_force_coeffs needs three finite numbers (c0, c1, c2)",
                               field="max_force_coeffs", value=self.max_force_coeffs,
                               allowed="(c0 N, c1, c2 1/N)")
        object.__setattr__(self, "max_force_coeffs", coeffs)
        object.__setattr__(self, "law", SlipLaw(self.law))
        if self.a_per_n is not None:
            _check("a_per_n", self.a_per_n, low=0.0, high=1.0)
        elif self.law is SlipLaw.VELOCITY:
            raise ProfileError("the velocity law [000 Eq. 8] needs a", field="a_per_n",
                               value=None, allowed="0 <= a <= 1 (fraction/N)")
        if self.b_per_n != 0.0 and self.c_s_per_mm <= 0.0:
            raise ProfileError("a velocity term b needs a decay c > 0", field="c_s_per_mm",
                               value=self.c_s_per_mm, allowed="> 0 s/mm when b != 0")

    @classmethod
    def from_roller(cls, roller: Roller, *, law: SlipLaw = SlipLaw.PINCH, k_p: float = 0.0,
                    max_force_scatter: float = 0.0,
                    grind_residual_fraction: float = 0.5,
                    roller_id: str | None = None) -> DriveUnderTest:
        """The drive under test for a roller of [000] (or a custom roller).

        Parameters
        ----------
        roller
            Roller with Table 3 parameters and a maximum-feed-force fit
            (:func:`flowtwin.profiles.load_rollers`).
        law
            Slip-gradient law.
        k_p
            Slip offset of the stand, fraction.
        max_force_scatter, grind_residual_fraction
            See the class attributes.
        roller_id
            Label for the records (default: the roller number, or ``"custom"``).

        Returns
        -------
        DriveUnderTest

        Raises
        ------
        ProfileError
            If the roller has no maximum-feed-force fit, or the law needs parameters the
            roller does not have.
        """
        fit = roller.max_feed_force_fit
        if fit is None:
            raise ProfileError("the roller has no maximum-feed-force fit [000 Figs. 4-8]; the "
                               "test stand needs one to know when the drive fails",
                               field="max_feed_force_fit", value=roller.label,
                               allowed="a roller with [max_feed_force_fit]")
        label = roller_id or (str(roller.number) if roller.number is not None else "custom")
        return cls(roller_id=label, k_s_n=roller.k_s_n, k_inf_per_n=roller.k_inf_per_n,
                   max_force_coeffs=(fit.c0_N, fit.c1, fit.c2_per_N), law=law,
                   a_per_n=roller.a_per_n,
                   b_per_n=0.0 if roller.b_per_n is None else roller.b_per_n,
                   c_s_per_mm=0.0 if roller.c_s_per_mm is None else roller.c_s_per_mm,
                   k_p=k_p, max_force_scatter=max_force_scatter,
                   grind_residual_fraction=grind_residual_fraction)

    def velocity_term_mean(self) -> float:
        """``ē``: mean of ``exp(−c·v)`` over :data:`PAPER_SPEEDS_MM_S` (combined law)."""
        if self.b_per_n == 0.0:
            return 0.0
        return float(np.mean(np.exp(-self.c_s_per_mm * np.asarray(PAPER_SPEEDS_MM_S))))

    def slip_gradient_per_n(self, pinch_force_n: npt.ArrayLike,
                            speed_mm_s: npt.ArrayLike) -> FloatArray:
        """Slip gradient ``s'`` of the drive, 1/N (fraction of slip per newton).

        Parameters
        ----------
        pinch_force_n
            Pinch force ``F_p``, N (> 0), any shape.
        speed_mm_s
            Nominal feed velocity, mm/s (≥ 0), broadcast against ``pinch_force_n``.

        Returns
        -------
        ndarray
            ``s'`` by :attr:`law` ([000 Eq. 6], [000 Eq. 8] or their combination), broadcast
            shape.
        """
        if self.law is SlipLaw.VELOCITY:
            assert self.a_per_n is not None  # checked in __post_init__
            base = slip_gradient_velocity(speed_mm_s, self.a_per_n, self.b_per_n,
                                          self.c_s_per_mm)
            return base + 0.0 * np.asarray(pinch_force_n, dtype=np.float64)
        pinch = slip_gradient(pinch_force_n, self.k_s_n, self.k_inf_per_n)
        if self.law is SlipLaw.PINCH or self.b_per_n == 0.0:
            return pinch + 0.0 * np.asarray(speed_mm_s, dtype=np.float64)
        v = np.asarray(speed_mm_s, dtype=np.float64)
        return pinch + self.b_per_n * (np.exp(-self.c_s_per_mm * v) - self.velocity_term_mean())

    def max_feed_force_n(self, pinch_force_n: npt.ArrayLike) -> FloatArray:
        """Maximum feed force before the roller fails, N [000 Figs. 4–8] (trend, no scatter).

        Parameters
        ----------
        pinch_force_n
            Pinch force, N (≥ 0), any shape.

        Returns
        -------
        ndarray
            ``c0 + c1·F_p + c2·F_p²``, N, shape of the input.
        """
        return max_feed_force_n(pinch_force_n, self.max_force_coeffs)


@dataclass(frozen=True)
class Instrument:
    """Sensors of the stand [000 §3]; standard deviations are half the paper's 2σ values.

    Attributes
    ----------
    force_sigma_n
        Standard deviation of the feed-force and pinch-force load cells, N ("±2 N (2σ)").
    speed_sigma_mm_s
        Standard deviation of the encoder, mm/s ("0.05 mm/s (2σ)").
    sample_rate_hz
        Samples per second ("50 samples/s").
    pinch_crosstalk_fraction
        The feed-force load cell's "additional linearity error of 1 % of the pinch force",
        modelled as a constant offset per record drawn uniformly from
        ``±fraction·F_p``; 0 (default) leaves it out.
    """

    force_sigma_n: float = 1.0
    speed_sigma_mm_s: float = 0.025
    sample_rate_hz: float = 50.0
    pinch_crosstalk_fraction: float = 0.0

    def __post_init__(self) -> None:
        _check("force_sigma_n", self.force_sigma_n, low=0.0, high=100.0)
        _check("speed_sigma_mm_s", self.speed_sigma_mm_s, low=0.0, high=10.0)
        _check("sample_rate_hz", self.sample_rate_hz, low=0.0, high=1e5, low_open=True)
        _check("pinch_crosstalk_fraction", self.pinch_crosstalk_fraction, low=0.0, high=0.5)


@dataclass(frozen=True)
class Procedure:
    """The measurement algorithm and parameter grid of [000 §3].

    Attributes
    ----------
    pinch_forces_n
        Set pinch forces, N (default 10–150 N in 10 N steps).
    speeds_mm_s
        Set nominal feed velocities ``v_fil,nom = ω·r``, mm/s (default 0.5–15 mm/s).
    repeats
        Records per parameter set ("at least three times").
    force_ramp_n_s
        Rise of the simulated process force, N/s (4 N/s).
    release_n_s
        Fall of the process force after the stall, N/s (50 N/s).
    wait_s
        Wait after the release before the record stops, s (5 s).
    stall_speed_mm_s
        The encoder reading below which the stand detects a blockage, mm/s (0.05 mm/s).
    """

    pinch_forces_n: tuple[float, ...] = PAPER_PINCH_FORCES_N
    speeds_mm_s: tuple[float, ...] = PAPER_SPEEDS_MM_S
    repeats: int = 3
    force_ramp_n_s: float = 4.0
    release_n_s: float = 50.0
    wait_s: float = 5.0
    stall_speed_mm_s: float = 0.05
    _grid: tuple[tuple[float, float], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        pinch = tuple(float(f) for f in self.pinch_forces_n)
        speeds = tuple(float(v) for v in self.speeds_mm_s)
        if not pinch or not speeds:
            raise ProfileError("the procedure needs at least one pinch force and one speed",
                               field="pinch_forces_n" if not pinch else "speeds_mm_s",
                               value=[], allowed="one or more values")
        for f in pinch:
            _check("pinch_forces_n", f, low=0.0, high=1000.0, low_open=True)
        for v in speeds:
            _check("speeds_mm_s", v, low=0.0, high=1000.0, low_open=True)
        if not 1 <= self.repeats <= 1000:
            raise ProfileError("repeats out of range", field="repeats", value=self.repeats,
                               allowed="1 <= repeats <= 1000")
        _check("force_ramp_n_s", self.force_ramp_n_s, low=0.0, high=1e4, low_open=True)
        _check("release_n_s", self.release_n_s, low=0.0, high=1e5, low_open=True)
        _check("wait_s", self.wait_s, low=0.0, high=3600.0)
        _check("stall_speed_mm_s", self.stall_speed_mm_s, low=0.0, high=100.0, low_open=True)
        object.__setattr__(self, "pinch_forces_n", pinch)
        object.__setattr__(self, "speeds_mm_s", speeds)
        object.__setattr__(self, "_grid", tuple((f, v) for f in pinch for v in speeds))

    @property
    def parameter_sets(self) -> tuple[tuple[float, float], ...]:
        """``(pinch force N, speed mm/s)`` of every parameter set, in measurement order."""
        return self._grid
