"""Per-move parameter resolution and validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.dynamics import ExtrusionParams, resolve_per_move
from flowtwin.errors import ProfileError


def test_scalar_array_and_callable():
    temps = np.array([200.0, 210.0, 220.0])
    assert resolve_per_move(0.5, 3, name="x").tolist() == [0.5, 0.5, 0.5]
    assert resolve_per_move([1, 2, 3], 3, name="x").tolist() == [1.0, 2.0, 3.0]
    out = resolve_per_move(lambda t: t - 200.0, 3, name="x", temperature_c=temps)
    assert out.tolist() == [0.0, 10.0, 20.0]


def test_scalar_is_a_stride_zero_view():
    # one value for every move: no memory per move (a read-only view with stride 0)
    out = resolve_per_move(0.25, 1_000_000, name="x")
    assert out.shape == (1_000_000,) and out.strides == (0,)
    assert not out.flags.writeable
    assert out[999_999] == 0.25


def test_ranges_and_messages():
    with pytest.raises(ProfileError, match=r"\[x\].*move 1.*got -1.0"):
        resolve_per_move([1.0, -1.0], 2, name="x", lo=0.0)
    with pytest.raises(ProfileError, match="wrong shape"):
        resolve_per_move([1.0, 2.0], 3, name="x")
    with pytest.raises(ProfileError, match="inf"):
        resolve_per_move(math.inf, 1, name="x")
    assert resolve_per_move(math.inf, 1, name="x", allow_inf=True)[0] == math.inf
    with pytest.raises(ProfileError, match="nan"):
        resolve_per_move(math.nan, 1, name="x", allow_inf=True)


def test_extrusion_params_build():
    p = ExtrusionParams.build(2, lag_k_s=0.05, compliance_mm_per_n=0.01, filament_diameter_mm=1.75)
    assert p.filament_area_mm2 == pytest.approx(math.pi * 1.75**2 / 4)
    assert np.all(p.max_feed_force_n == math.inf)
    with pytest.raises(ProfileError, match="grind_release_fraction"):
        ExtrusionParams.build(1, lag_k_s=0.05, compliance_mm_per_n=0.01,
                              grind_release_fraction=1.0)
    with pytest.raises(ProfileError, match="slip_offset"):
        ExtrusionParams.build(1, lag_k_s=0.05, compliance_mm_per_n=0.01, slip_offset=1.0)
