"""Bead model [001 Eq. 7 = 003 Eq. 2], width, ooze and blobs."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from flowtwin.errors import DataError
from flowtwin.physics.deposition import (
    Deposit,
    bead_area_mm2,
    bead_width_mm,
    blob_diameter_mm,
    classify_deposit,
    deposit_volumes_mm3,
    filament_length_for_bead,
)


def test_001_eq7_equals_003_eq2() -> None:
    rng = np.random.default_rng(3)
    w = rng.uniform(0.2, 1.0, 100)
    h = rng.uniform(0.05, 0.4, 100)
    assert_allclose(bead_area_mm2(w, h), (w - h) * h + np.pi * (h / 2) ** 2, rtol=1e-13)
    # w = h: a circle of diameter h
    assert float(bead_area_mm2(0.3, 0.3)) == pytest.approx(np.pi * 0.3 ** 2 / 4)
    # Tronvoll's line: 0.48 mm × 0.2 mm [001 Table I]
    assert float(bead_area_mm2(0.48, 0.2)) == pytest.approx(0.48 * 0.2 - (1 - np.pi / 4) * 0.04)


def test_width_inverts_area_and_flags() -> None:
    h = 0.2
    v = np.array([40.0, 40.0, 40.0, 0.0])
    q = np.array([3.5, 1.5, 0.5, 2.0])  # w = 0.48, 0.23, 0.105 mm at 40 mm/s
    bead = bead_width_mm(q, h, v)
    moving = ~bead.stationary
    assert bead.stationary.tolist() == [False, False, False, True]
    assert np.isnan(bead.width_mm[3])
    # mass balance: A(w)·v = Q
    assert_allclose(bead_area_mm2(bead.width_mm[moving], h) * v[moving], q[moving])
    # w < h is ill-defined [001 Fig. 12]: flagged, not hidden
    assert bead.narrower_than_height.tolist() == [False, False, True, False]
    assert bead.width_mm[2] < h


def test_filament_length_conserves_volume() -> None:
    area_fil = np.pi * 1.75 ** 2 / 4
    e = filament_length_for_bead(0.48, 0.2, 100.0, area_fil)
    assert float(e) * area_fil == pytest.approx(float(bead_area_mm2(0.48, 0.2)) * 100.0)


def test_ooze_and_blob_accounting() -> None:
    speed = np.array([50.0, 50.0, 0.0, 120.0, 0.0])
    extruding = np.array([True, True, True, False, False])
    labels = classify_deposit(speed, extruding)
    assert labels.tolist() == [Deposit.BEAD, Deposit.BEAD, Deposit.BLOB, Deposit.OOZE,
                               Deposit.BLOB]
    q = np.array([3.0, 2.0, 1.5, 0.4, 0.2])
    vols = deposit_volumes_mm3(q, 0.1, labels)
    assert vols.bead_mm3 == pytest.approx(0.5)
    assert vols.ooze_mm3 == pytest.approx(0.04)
    assert vols.blob_mm3 == pytest.approx(0.17)
    assert sum(vols) == pytest.approx(float(np.sum(q * 0.1)))
    with pytest.raises(DataError, match="no backflow"):
        deposit_volumes_mm3(np.array([-1.0]), 0.1, labels[:1])


def test_blob_diameter_is_disc_of_layer_height() -> None:
    d = blob_diameter_mm(2.0, 0.2)
    assert float(np.pi * d ** 2 / 4 * 0.2) == pytest.approx(2.0)
