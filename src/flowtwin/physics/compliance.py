"""Filament column between drive roller and melt: compliance ``k`` in ``Δl = k·F`` [002, 001].

The column shortens under the feed force like two springs in series, a cold part of length
``l_RT`` with Young's modulus ``E_RT`` and a hot part (above the glass transition) of length
``l_hot`` with a much lower modulus ``E_hot`` [002]:

``Δl = F/A_fil·(l_RT/E_RT + l_hot/E_hot)``  [002], i.e. ``Δl = k·F``  [001 Eq. 2].

Beyond the seeds (docs/spec.md §3.2) a Bowden tube adds two series compliances, both linear in the
force and both off for a direct drive:

* the tube wall stretches, because it carries the reaction of the feed force in tension:
  ``k_tube = L_tube/(E_tube·A_wall)``, ``A_wall = π(D_o² − D_i²)/4``;
* the filament takes up the radial clearance ``e = (D_i − d)/2`` by buckling into a helix
  inside the tube. For a weightless rod in a tube the helix pitch obeys
  ``F = 8π²EI/p²`` and the axial shortening per length is ``2π²e²/p²``, so
  ``Δl = L·e²·F/(4·E·I)`` with ``I = πd⁴/64`` (Lubinski, "Helical buckling of tubing sealed
  in packers", J. Petrol. Technol. 1962). This is the clearance take-up.

The axial compression of the filament inside the tube is the cold-column term: include the
tube length in ``l_rt_mm`` of :func:`compliance_mm_per_n`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.physics._checks import require_nonnegative, require_positive

__all__ = [
    "bowden_compliance_mm_per_n",
    "compliance_mm_per_n",
    "compression_mm",
    "helical_buckling_compliance_mm_per_n",
    "tube_stretch_compliance_mm_per_n",
]

FloatArray = npt.NDArray[np.float64]


def compliance_mm_per_n(filament_area_mm2: npt.ArrayLike, l_rt_mm: npt.ArrayLike,
                        e_rt_mpa: npt.ArrayLike, l_hot_mm: npt.ArrayLike,
                        e_hot_mpa: npt.ArrayLike) -> FloatArray:
    """Column compliance ``k = (l_RT/E_RT + l_hot/E_hot)/A_fil`` [002; 001 Eq. 2].

    Parameters
    ----------
    filament_area_mm2
        Filament cross-section ``A_fil``, mm² (> 0).
    l_rt_mm
        Length of cold filament from the roller to the melt zone (plus any Bowden tube), mm
        (≥ 0).
    e_rt_mpa
        Young's modulus of the cold filament, MPa (> 0); about 3.5 GPa for PLA.
    l_hot_mm
        Length of hot (above T_g) filament, mm (≥ 0).
    e_hot_mpa
        Effective modulus of the hot filament, MPa (> 0); not given by the seeds, see
        :mod:`flowtwin.physics.defaults`.

    Returns
    -------
    ndarray
        Compliance ``k``, mm/N, broadcast shape.
    """
    area = require_positive("filament_area_mm2", filament_area_mm2)
    cold = require_nonnegative("l_rt_mm", l_rt_mm) / require_positive("e_rt_mpa", e_rt_mpa)
    hot = require_nonnegative("l_hot_mm", l_hot_mm) / require_positive("e_hot_mpa", e_hot_mpa)
    return (cold + hot) / area


def compression_mm(force_n: npt.ArrayLike, k_mm_per_n: npt.ArrayLike) -> FloatArray:
    """Column shortening ``Δl = k·F`` [001 Eq. 2].

    Parameters
    ----------
    force_n
        Feed force, N, any shape.
    k_mm_per_n
        Compliance ``k``, mm/N (≥ 0), e.g. from :func:`compliance_mm_per_n`.

    Returns
    -------
    ndarray
        ``Δl``, mm, broadcast shape.
    """
    return np.asarray(force_n, dtype=np.float64) * require_nonnegative("k_mm_per_n",
                                                                       k_mm_per_n)


def tube_stretch_compliance_mm_per_n(tube_length_mm: npt.ArrayLike,
                                     tube_outer_diameter_mm: npt.ArrayLike,
                                     tube_inner_diameter_mm: npt.ArrayLike,
                                     tube_modulus_mpa: npt.ArrayLike) -> FloatArray:
    """Stretch of a Bowden tube wall, ``L/(E·π(D_o² − D_i²)/4)`` (beyond the seeds).

    Parameters
    ----------
    tube_length_mm
        Tube length, mm (> 0).
    tube_outer_diameter_mm, tube_inner_diameter_mm
        Tube diameters, mm (outer > inner > 0).
    tube_modulus_mpa
        Young's modulus of the wall, MPa (> 0); PTFE is of order 500 MPa.

    Returns
    -------
    ndarray
        Compliance, mm/N, broadcast shape.
    """
    d_o = require_positive("tube_outer_diameter_mm", tube_outer_diameter_mm)
    d_i = require_positive("tube_inner_diameter_mm", tube_inner_diameter_mm)
    if np.any(d_o <= d_i):
        raise ProfileError("the tube outer diameter must exceed its inner diameter",
                           field="tube_outer_diameter_mm", value=d_o.tolist(),
                           allowed=f"> inner diameter {d_i.tolist()}")
    wall = np.pi * (d_o * d_o - d_i * d_i) / 4.0
    return require_positive("tube_length_mm", tube_length_mm) / (
        require_positive("tube_modulus_mpa", tube_modulus_mpa) * wall)


def helical_buckling_compliance_mm_per_n(length_mm: npt.ArrayLike,
                                         tube_inner_diameter_mm: npt.ArrayLike,
                                         filament_diameter_mm: npt.ArrayLike,
                                         filament_modulus_mpa: npt.ArrayLike) -> FloatArray:
    """Clearance take-up of a filament buckling into a helix in a tube, ``L·e²/(4EI)``.

    Lubinski's weightless helical buckling (see module docstring): pitch ``p`` with
    ``F = 8π²EI/p²``; shortening ``Δl/L = 2π²e²/p² = e²F/(4EI)``, ``e = (D_i − d)/2``,
    ``I = πd⁴/64`` (beyond the seeds).

    Parameters
    ----------
    length_mm
        Length of filament inside the tube, mm (> 0).
    tube_inner_diameter_mm
        Tube bore, mm (≥ filament diameter).
    filament_diameter_mm
        Filament diameter, mm (> 0).
    filament_modulus_mpa
        Young's modulus of the (cold) filament, MPa (> 0).

    Returns
    -------
    ndarray
        Compliance, mm/N, broadcast shape (0 when the bore equals the filament diameter).
    """
    d = require_positive("filament_diameter_mm", filament_diameter_mm)
    bore = require_positive("tube_inner_diameter_mm", tube_inner_diameter_mm)
    if np.any(bore < d):
        raise ProfileError("the tube bore is narrower than the filament",
                           field="tube_inner_diameter_mm", value=bore.tolist(),
                           allowed=f">= filament diameter {d.tolist()}")
    clearance = (bore - d) / 2.0
    inertia = np.pi * d ** 4 / 64.0
    return require_positive("length_mm", length_mm) * clearance * clearance / (
        4.0 * require_positive("filament_modulus_mpa", filament_modulus_mpa) * inertia)


def bowden_compliance_mm_per_n(tube_length_mm: npt.ArrayLike,
                               tube_outer_diameter_mm: npt.ArrayLike,
                               tube_inner_diameter_mm: npt.ArrayLike,
                               tube_modulus_mpa: npt.ArrayLike,
                               filament_diameter_mm: npt.ArrayLike,
                               filament_modulus_mpa: npt.ArrayLike) -> FloatArray:
    """Extra compliance of a Bowden tube: wall stretch + helical clearance take-up.

    Add it to :func:`compliance_mm_per_n` (whose ``l_rt_mm`` must include the tube length
    for the axial compression of the filament). Beyond the seeds (docs/spec.md §3.2).

    Parameters
    ----------
    tube_length_mm, tube_outer_diameter_mm, tube_inner_diameter_mm, tube_modulus_mpa
        See :func:`tube_stretch_compliance_mm_per_n`.
    filament_diameter_mm, filament_modulus_mpa
        See :func:`helical_buckling_compliance_mm_per_n`.

    Returns
    -------
    ndarray
        Compliance, mm/N, broadcast shape.
    """
    return tube_stretch_compliance_mm_per_n(
        tube_length_mm, tube_outer_diameter_mm, tube_inner_diameter_mm, tube_modulus_mpa
    ) + helical_buckling_compliance_mm_per_n(
        tube_length_mm, tube_inner_diameter_mm, filament_diameter_mm, filament_modulus_mpa)
