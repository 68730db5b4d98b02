"""A material profile's viscosity law evaluated at temperatures (the laws are
:mod:`flowtwin.physics.viscosity`'s)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin.physics.viscosity import (
    viscosity_arrhenius_pa_s,
    viscosity_exponential_pa_s,
    viscosity_wlf_pa_s,
)
from flowtwin.profiles.material import (
    ArrheniusViscosity,
    ExponentialViscosity,
    MaterialProfile,
    WlfViscosity,
)

__all__ = ["viscosity_pa_s"]


def viscosity_pa_s(material: MaterialProfile, temp_c: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Melt viscosity by the material's law (exponential [002], Arrhenius or WLF), Pa·s.

    Parameters
    ----------
    material
        The material profile (its ``viscosity`` law).
    temp_c
        Melt temperatures, °C, any shape.

    Returns
    -------
    ndarray
        Viscosity, Pa·s, the shape of ``temp_c``.
    """
    law = material.viscosity
    t = np.asarray(temp_c, dtype=np.float64)
    if isinstance(law, ExponentialViscosity):
        return viscosity_exponential_pa_s(t, law.mu0_pa_s, law.b_per_c)
    if isinstance(law, ArrheniusViscosity):
        return viscosity_arrhenius_pa_s(t, law.mu_ref_pa_s, law.t_ref_c,
                                        law.activation_energy_j_mol)
    assert isinstance(law, WlfViscosity)
    return viscosity_wlf_pa_s(t, law.mu_ref_pa_s, law.t_ref_c, law.c1, law.c2_k)
