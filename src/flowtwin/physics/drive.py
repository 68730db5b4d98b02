"""Filament drive (cold end): slip, pinch force, maximum feed force, grinding [000].

Nienhaus, Spiehl and Dörsam [000] measured seven drive rollers on a test stand and found
that the slip grows linearly with the feed force ``F_f`` and falls with the pinch force
``F_p`` as ``s = k_p + (k_s/F_p² + k_∞)·F_f`` [000 Eq. 6]; at pinch forces of 80–130 N the
slip gradient falls with the feed velocity as ``s' = a + b·exp(−c·v_fil)`` [000 Eq. 8]. The
maximum feed force the roller can transmit before it eats into the filament is a 2nd-order
polynomial of the pinch force [000 Figs. 4–8].

Units: forces N, velocities mm/s, slip a fraction (not %). The paper's parameters are in
percent (``k_s`` %·N, ``k_∞``, ``a``, ``b`` %/N [000 Table 3]); divide them by 100 (see
:func:`flowtwin.physics.units.percent_to_fraction`). ``c`` is in s/mm (``c·v_fil`` is
dimensionless with ``v_fil`` in mm/s). Equation 9 is the same in either unit system because
it depends only on the ratio ``k_s/k_∞``.

All functions broadcast numpy arrays and accept floats (a float input gives a numpy
scalar result).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError, ProfileError
from flowtwin.physics._checks import (
    as_float_array,
    require_finite,
    require_nonnegative,
    require_positive,
)

__all__ = [
    "feed_velocity_mm_s",
    "feed_velocity_rough_mm_s",
    "is_grinding",
    "max_feed_force_n",
    "measured_slip",
    "min_pinch_force_n",
    "slip",
    "slip_gradient",
    "slip_gradient_velocity",
    "slip_velocity",
    "steady_slip_at_intended_feed",
    "steady_state_slip",
]

FloatArray = npt.NDArray[np.float64]


def measured_slip(omega_r_mm_s: npt.ArrayLike, v_fil_mm_s: npt.ArrayLike) -> FloatArray:
    """Measured slip ``s_m = (ω·r − v_fil)/(ω·r)`` [000 Eq. 1].

    Parameters
    ----------
    omega_r_mm_s
        Nominal feed velocity ``v_fil,nom = ω·r`` of the roller surface, mm/s; must be > 0.
    v_fil_mm_s
        Measured filament velocity, mm/s (broadcast against ``omega_r_mm_s``).

    Returns
    -------
    ndarray
        Slip as a fraction (0 = no slip, 1 = filament stands still), broadcast shape.

    Raises
    ------
    DataError
        If any nominal velocity is not positive (slip is undefined while the roller stands).
    """
    nominal = as_float_array(omega_r_mm_s)
    if not np.all(np.isfinite(nominal) & (nominal > 0.0)):
        raise DataError("measured slip needs a positive nominal feed velocity ω·r",
                        field="omega_r_mm_s",
                        value=float(np.min(nominal)) if nominal.size else None,
                        allowed="> 0 mm/s (drop samples where the roller stands)")
    return (nominal - as_float_array(v_fil_mm_s)) / nominal


def slip_gradient(pinch_force_n: npt.ArrayLike, k_s_n: npt.ArrayLike,
                  k_inf_per_n: npt.ArrayLike) -> FloatArray:
    """Slip gradient against pinch force ``s' = k_s/F_p² + k_∞`` [000 Eq. 6].

    Parameters
    ----------
    pinch_force_n
        Pinch force ``F_p`` between the rollers, N (> 0), any shape.
    k_s_n
        ``k_s`` as a fraction·N (Table 3 value in %·N divided by 100) [000 Table 3].
    k_inf_per_n
        ``k_∞``, fraction per N (Table 3 value in %/N divided by 100) [000 Table 3].

    Returns
    -------
    ndarray
        ``s'`` in 1/N (slip fraction per newton of feed force), broadcast shape.
    """
    fp = require_positive("pinch_force_n", pinch_force_n)
    return require_nonnegative("k_s_n", k_s_n) / (fp * fp) + require_nonnegative(
        "k_inf_per_n", k_inf_per_n)


def slip(feed_force_n: npt.ArrayLike, pinch_force_n: npt.ArrayLike, *,
         k_p: npt.ArrayLike, k_s_n: npt.ArrayLike, k_inf_per_n: npt.ArrayLike) -> FloatArray:
    """Slip against feed and pinch force ``s = k_p + (k_s/F_p² + k_∞)·F_f`` [000 Eq. 6].

    Parameters
    ----------
    feed_force_n
        Feed force ``F_f`` the roller transmits, N (≥ 0 while feeding), any shape.
    pinch_force_n
        Pinch force ``F_p``, N (> 0).
    k_p
        Set-up specific offset, fraction (found by calibration [000 §4.2]).
    k_s_n, k_inf_per_n
        See :func:`slip_gradient`.

    Returns
    -------
    ndarray
        Slip fraction, broadcast shape. The law is linear and is not clipped: values near
        or above 1 mean the drive is failing (check :func:`is_grinding`).
    """
    gradient = slip_gradient(pinch_force_n, k_s_n, k_inf_per_n)
    return require_finite("k_p", k_p) + gradient * as_float_array(feed_force_n)


def slip_gradient_velocity(v_fil_mm_s: npt.ArrayLike, a_per_n: npt.ArrayLike,
                           b_per_n: npt.ArrayLike, c_s_per_mm: npt.ArrayLike) -> FloatArray:
    """Slip gradient against feed velocity ``s' = a + b·exp(−c·v_fil)`` [000 Eq. 8].

    Valid for pinch forces of 80–130 N only [000 §4.2]; ``a`` and ``b`` contain the factor
    ``F_p^-2`` of Eq. 6 at that pinch force.

    Parameters
    ----------
    v_fil_mm_s
        Feed velocity, mm/s (≥ 0), any shape.
    a_per_n
        ``a``, fraction per N (Table 3 value in %/N divided by 100).
    b_per_n
        ``b``, fraction per N. Rollers without velocity dependence (#6, #7, whose Table 3
        rows read ``b → ∞, c → ∞`` and ``b → 0, c → ∞``: the second term vanishes) are
        represented by ``b = 0``; then ``s' = a`` for every ``c``.
    c_s_per_mm
        ``c``, s/mm (≥ 0; ``numpy.inf`` is accepted and makes the term vanish for
        ``v_fil > 0``).

    Returns
    -------
    ndarray
        ``s'`` in 1/N, broadcast shape.
    """
    v = require_nonnegative("v_fil_mm_s", v_fil_mm_s)
    a = require_nonnegative("a_per_n", a_per_n)
    b = require_nonnegative("b_per_n", b_per_n)
    c = as_float_array(c_s_per_mm)
    if np.any(np.isnan(c) | (c < 0.0)):
        raise ProfileError("c of the velocity law must be >= 0", field="c_s_per_mm",
                        value=c.tolist(), allowed=">= 0 s/mm (inf allowed)")
    with np.errstate(invalid="ignore", over="ignore"):
        decay = np.exp(-c * v)
        term = np.where(b == 0.0, 0.0, b * decay)
    return a + term


def slip_velocity(feed_force_n: npt.ArrayLike, v_fil_mm_s: npt.ArrayLike, *,
                  k_p: npt.ArrayLike, a_per_n: npt.ArrayLike, b_per_n: npt.ArrayLike,
                  c_s_per_mm: npt.ArrayLike) -> FloatArray:
    """Slip with the velocity law ``s = k_p + (a + b·exp(−c·v_fil))·F_f`` [000 Eq. 8].

    Parameters
    ----------
    feed_force_n
        Feed force, N, any shape.
    v_fil_mm_s
        Feed velocity, mm/s.
    k_p
        Set-up specific offset, fraction.
    a_per_n, b_per_n, c_s_per_mm
        See :func:`slip_gradient_velocity`.

    Returns
    -------
    ndarray
        Slip fraction, broadcast shape.
    """
    gradient = slip_gradient_velocity(v_fil_mm_s, a_per_n, b_per_n, c_s_per_mm)
    return require_finite("k_p", k_p) + gradient * as_float_array(feed_force_n)


def min_pinch_force_n(k_s_n: npt.ArrayLike, k_inf_per_n: npt.ArrayLike, *,
                      tolerance: float = 0.1) -> FloatArray:
    """Minimal pinch force ``F_p,min = sqrt(k_s/(0.1·k_∞))`` [000 Eq. 9].

    At ``F_p,min`` the slip gradient is within ``tolerance`` (10 % in the paper) of its
    floor ``k_∞``: ``s'(F_p,min) = (1 + tolerance)·k_∞``.

    Parameters
    ----------
    k_s_n
        ``k_s`` (fraction·N or %·N: only the ratio matters), any shape.
    k_inf_per_n
        ``k_∞`` in the same percent/fraction convention as ``k_s_n``; > 0.
    tolerance
        Relative excess of ``s'`` over ``k_∞`` accepted, > 0 (the paper uses 0.1).

    Returns
    -------
    ndarray
        ``F_p,min`` in N, broadcast shape.
    """
    tol = require_positive("tolerance", tolerance)
    return np.sqrt(require_nonnegative("k_s_n", k_s_n)
                   / (tol * require_positive("k_inf_per_n", k_inf_per_n)))


def max_feed_force_n(pinch_force_n: npt.ArrayLike, coeffs: Sequence[float]) -> FloatArray:
    """Maximum feed force before the drive fails, ``c0 + c1·F_p + c2·F_p²`` [000 Figs. 4–8].

    The paper fits a 2nd-order polynomial of the pinch force over all feed velocities for
    each roller, e.g. roller #3: ``F_f,fit = −6.03e-3·F_p² + 1.52·F_p + 7.5`` [000 Fig. 6],
    i.e. ``coeffs = (7.5, 1.52, -6.03e-3)``. The fits are valid for 10–150 N.

    Parameters
    ----------
    pinch_force_n
        Pinch force, N (≥ 0), any shape.
    coeffs
        ``(c0, c1, c2)``: N, dimensionless, 1/N — constant term first.

    Returns
    -------
    ndarray
        Maximum feed force, N, shape of ``pinch_force_n``.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ProfileError("the maximum feed force needs three finite coefficients (c0, c1, c2)",
                        field="coeffs", value=c.tolist(), allowed="(c0, c1, c2)")
    fp = require_nonnegative("pinch_force_n", pinch_force_n)
    return c[0] + fp * (c[1] + fp * c[2])


def is_grinding(feed_force_n: npt.ArrayLike,
                max_feed_force_n: npt.ArrayLike) -> npt.NDArray[np.bool_]:
    """True where the feed force exceeds the maximum feed force (the roller grinds).

    Above the maximum feed force the roller eats into the filament and feeding stops
    [000 §4, 003 "filament shredding"].

    Parameters
    ----------
    feed_force_n
        Feed force, N, any shape.
    max_feed_force_n
        Maximum feed force of the drive, N (see :func:`max_feed_force_n`), broadcast.

    Returns
    -------
    ndarray of bool
        Broadcast shape.
    """
    return np.asarray(as_float_array(feed_force_n) > as_float_array(max_feed_force_n))


def steady_state_slip(nominal_feed_force_n: npt.ArrayLike,
                      slip_gradient_per_n: npt.ArrayLike, *,
                      k_p: npt.ArrayLike = 0.0) -> FloatArray:
    """Steady slip when the feed force is proportional to the delivered flow.

    In steady extrusion the feed force is ``F_f = F_0·(1 − s)``, where ``F_0`` is the force
    the nominal feed velocity ``ω·r`` would need (pressure ∝ flow, docs/spec.md §3.3–3.4). Inserting
    this into Eq. 6 of [000], ``s = k_p + s'·F_0·(1 − s)``, gives

    ``s = (k_p + s'·F_0)/(1 + s'·F_0)``.

    Parameters
    ----------
    nominal_feed_force_n
        ``F_0``, N (≥ 0), any shape.
    slip_gradient_per_n
        ``s'``, 1/N (from :func:`slip_gradient` or :func:`slip_gradient_velocity`).
    k_p
        Offset, fraction.

    Returns
    -------
    ndarray
        Steady slip fraction, broadcast shape; the delivered force is ``F_0·(1 − s)``.
    """
    g_f0 = require_nonnegative("slip_gradient_per_n", slip_gradient_per_n) * \
        require_nonnegative("nominal_feed_force_n", nominal_feed_force_n)
    return (require_finite("k_p", k_p) + g_f0) / (1.0 + g_f0)


def steady_slip_at_intended_feed(slip: npt.ArrayLike, *,
                                 k_p: npt.ArrayLike = 0.0) -> FloatArray:
    """Steady slip once the feed is raised so that the drive delivers the intended feed.

    At the intended feed the drive slips by ``s`` (:func:`steady_state_slip`), so it
    delivers ``(1 − s)`` of it and the force is ``F_0·(1 − s)``. Commanding
    ``1/(1 − s*)`` of the feed delivers the intended feed again, the force is back at
    ``F_0``, and [000 Eq. 6] gives ``s* = k_p + s'·F_0``. With
    ``s'·F_0 = (s − k_p)/(1 − s)`` from the steady slip,

    ``s* = s·(1 − k_p)/(1 − s)``:

    the fixed point of the slip feed-forward ``E' = E/(1 − s(E'))`` [000 §6] from the slip
    predicted at the uncorrected feed (pressure ∝ flow, docs/spec.md §3.3–3.4).

    Parameters
    ----------
    slip
        Steady slip ``s`` at the intended feed, fraction in ``[0, 1)``, any shape.
    k_p
        Offset of Eq. 6, fraction, broadcast.

    Returns
    -------
    ndarray
        ``s*``, fraction, broadcast shape (0 where ``s`` is 0).

    Raises
    ------
    DataError
        A slip outside ``[0, 1)`` or not finite.
    """
    s = as_float_array(slip)
    if not np.all((s >= 0.0) & (s < 1.0)):
        bad = s[~((s >= 0.0) & (s < 1.0))].flat[0]
        raise DataError("slip out of range", field="slip", value=float(bad),
                        allowed="0 <= s < 1")
    return np.asarray(s * (1.0 - require_finite("k_p", k_p)) / (1.0 - s))


def feed_velocity_mm_s(print_speed_mm_s: npt.ArrayLike, bead_area_mm2: npt.ArrayLike,
                       filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Feed velocity for a bead, ``v_fil = A_bead·v_print/A_fil`` (docs/spec.md §3.1).

    Mass conservation at constant density, the exact form behind [000 Eq. 2].

    Parameters
    ----------
    print_speed_mm_s
        Print (nozzle) speed, mm/s, any shape.
    bead_area_mm2
        Bead cross-section, mm² (e.g. :func:`flowtwin.physics.deposition.bead_area_mm2`).
    filament_area_mm2
        Filament cross-section, mm² (> 0).

    Returns
    -------
    ndarray
        Filament feed velocity, mm/s, broadcast shape.
    """
    return as_float_array(bead_area_mm2) * as_float_array(print_speed_mm_s) / \
        require_positive("filament_area_mm2", filament_area_mm2)


def feed_velocity_rough_mm_s(print_speed_mm_s: npt.ArrayLike, d_out_mm: npt.ArrayLike,
                             d_in_mm: npt.ArrayLike) -> FloatArray:
    """The paper's rough estimate ``v_fil ≈ (d_out/d_in)²·v_print`` [000 Eq. 2].

    Treats the strand as a cylinder of the nozzle diameter; it ignores the bead shape, so
    use :func:`feed_velocity_mm_s` for a real bead. For 0.4 mm / 1.75 mm the factor is
    ≈ 0.05 [000 Eq. 2].

    Parameters
    ----------
    print_speed_mm_s
        Print speed, mm/s, any shape.
    d_out_mm
        Nozzle capillary diameter, mm (> 0).
    d_in_mm
        Filament diameter, mm (> 0).

    Returns
    -------
    ndarray
        Feed velocity, mm/s, broadcast shape.
    """
    ratio = require_positive("d_out_mm", d_out_mm) / require_positive("d_in_mm", d_in_mm)
    return ratio * ratio * as_float_array(print_speed_mm_s)
