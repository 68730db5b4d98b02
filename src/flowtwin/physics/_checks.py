"""Parameter checks shared by the physics functions (private).

The physics functions are pure maths on arrays; they check only the *parameters* whose
bad values would otherwise give a silently wrong number (a zero radius, a negative
modulus). A failed check raises :class:`flowtwin.errors.ProfileError` naming the parameter,
the value and what is allowed, because such parameters come from a profile.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError

__all__ = ["as_float_array", "require_finite", "require_nonnegative", "require_positive"]


def as_float_array(value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return ``value`` as a float64 array (0-d for a scalar) without copying if possible."""
    return np.asarray(value, dtype=np.float64)


def _shown(arr: npt.NDArray[np.float64]) -> object:
    return float(arr) if arr.ndim == 0 else arr.tolist()


def require_positive(name: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return ``value`` as an array; raise ProfileError unless every element is finite > 0."""
    arr = as_float_array(value)
    if not np.all(np.isfinite(arr) & (arr > 0.0)):
        raise ProfileError(f"{name} must be finite and positive", field=name,
                           value=_shown(arr), allowed="> 0")
    return arr


def require_nonnegative(name: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return ``value`` as an array; raise ProfileError unless every element is finite >= 0."""
    arr = as_float_array(value)
    if not np.all(np.isfinite(arr) & (arr >= 0.0)):
        raise ProfileError(f"{name} must be finite and non-negative", field=name,
                           value=_shown(arr), allowed=">= 0")
    return arr


def require_finite(name: str, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return ``value`` as an array; raise ProfileError unless every element is finite."""
    arr = as_float_array(value)
    if not np.all(np.isfinite(arr)):
        raise ProfileError(f"{name} must be finite", field=name, value=_shown(arr),
                           allowed="a finite number")
    return arr
