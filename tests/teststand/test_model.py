"""The drive under test follows [000 Eq. 6] / [000 Eq. 8] and validates its parameters."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.errors import ProfileError
from flowtwin.physics.drive import max_feed_force_n, slip_gradient, slip_gradient_velocity
from flowtwin.profiles import load_rollers
from flowtwin.teststand import (
    PAPER_PINCH_FORCES_N,
    PAPER_SPEEDS_MM_S,
    DriveUnderTest,
    Instrument,
    Procedure,
    SlipLaw,
)

ROLLERS = load_rollers()


def test_paper_grid() -> None:
    # [000 §3]: 10-150 N in 10 N steps, 0.5-1-2-5-10-15 mm/s, at least three repeats
    assert PAPER_PINCH_FORCES_N == tuple(float(f) for f in range(10, 151, 10))
    assert PAPER_SPEEDS_MM_S == (0.5, 1.0, 2.0, 5.0, 10.0, 15.0)
    proc = Procedure()
    assert proc.repeats == 3
    assert len(proc.parameter_sets) == 15 * 6  # 270 records with 3 repeats [000 §3]
    assert (proc.force_ramp_n_s, proc.release_n_s, proc.wait_s, proc.stall_speed_mm_s) == \
        (4.0, 50.0, 5.0, 0.05)


def test_instrument_is_half_the_papers_two_sigma() -> None:
    inst = Instrument()
    assert inst.force_sigma_n == 2.0 / 2  # "±2 N (2 sigma)"
    assert inst.speed_sigma_mm_s == 0.05 / 2  # "0.05 mm/s (2 sigma)"
    assert inst.sample_rate_hz == 50.0


@pytest.mark.parametrize("number", sorted(ROLLERS))
def test_pinch_law_is_eq6(number: int) -> None:
    roller = ROLLERS[number]
    drive = DriveUnderTest.from_roller(roller, law=SlipLaw.PINCH)
    fp = np.array(PAPER_PINCH_FORCES_N)
    expected = slip_gradient(fp, roller.k_s_n, roller.k_inf_per_n)
    np.testing.assert_allclose(drive.slip_gradient_per_n(fp, 1.0), expected, rtol=1e-15)
    # and the Table 3 numbers themselves: s'(80 N) of roller #3 = 96/80^2 + 0.32 %/N
    if number == 3:
        assert 100 * float(drive.slip_gradient_per_n(80.0, 1.0)) == pytest.approx(0.335)


@pytest.mark.parametrize("number", sorted(ROLLERS))
def test_velocity_law_is_eq8(number: int) -> None:
    roller = ROLLERS[number]
    drive = DriveUnderTest.from_roller(roller, law=SlipLaw.VELOCITY)
    v = np.array(PAPER_SPEEDS_MM_S)
    b = roller.b_per_n or 0.0
    c = roller.c_s_per_mm or 0.0
    assert roller.a_per_n is not None
    expected = slip_gradient_velocity(v, roller.a_per_n, b, c)
    np.testing.assert_allclose(drive.slip_gradient_per_n(100.0, v), expected, rtol=1e-15)
    # no pinch dependence in this law
    np.testing.assert_allclose(drive.slip_gradient_per_n(80.0, v),
                               drive.slip_gradient_per_n(130.0, v), rtol=0)


@pytest.mark.parametrize("number", [1, 3, 5])
def test_combined_law_averages_to_eq6_over_the_paper_speeds(number: int) -> None:
    roller = ROLLERS[number]
    drive = DriveUnderTest.from_roller(roller, law=SlipLaw.COMBINED)
    v = np.array(PAPER_SPEEDS_MM_S)
    for fp in (10.0, 80.0, 150.0):
        mean = float(np.mean(drive.slip_gradient_per_n(fp, v)))
        assert mean == pytest.approx(float(slip_gradient(fp, roller.k_s_n, roller.k_inf_per_n)),
                                     rel=1e-12)
    # the velocity shape is Eq. 8's: differences between speeds equal b·Δexp(−c·v)
    g = drive.slip_gradient_per_n(100.0, v)
    b, c = roller.b_per_n, roller.c_s_per_mm
    assert b is not None and c is not None
    np.testing.assert_allclose(g - g[-1], b * (np.exp(-c * v) - np.exp(-c * 15.0)),
                               rtol=1e-12, atol=1e-15)


def test_max_force_is_the_figure_fit() -> None:
    roller = ROLLERS[3]
    drive = DriveUnderTest.from_roller(roller)
    fp = np.array(PAPER_PINCH_FORCES_N)
    np.testing.assert_allclose(drive.max_feed_force_n(fp),
                               max_feed_force_n(fp, (7.5, 1.52, -6.03e-3)), rtol=1e-15)


def test_velocity_law_needs_a() -> None:
    with pytest.raises(ProfileError, match="needs a"):
        DriveUnderTest(roller_id="x", k_s_n=1.0, k_inf_per_n=0.003,
                       max_force_coeffs=(0.0, 1.0, 0.0), law=SlipLaw.VELOCITY)


@pytest.mark.parametrize(("field", "value"), [
    ("k_inf_per_n", -0.1), ("k_s_n", float("nan")), ("max_force_scatter", 0.9),
    ("grind_residual_fraction", 1.0), ("k_p", 0.7)])
def test_bad_drive_parameters_name_the_field(field: str, value: float) -> None:
    kwargs = {"roller_id": "x", "k_s_n": 1.0, "k_inf_per_n": 0.003,
              "max_force_coeffs": (0.0, 1.0, 0.0), field: value}
    with pytest.raises(ProfileError, match=field):
        DriveUnderTest(**kwargs)  # type: ignore[arg-type]


def test_bad_procedure_and_instrument() -> None:
    with pytest.raises(ProfileError, match="pinch_forces_n"):
        Procedure(pinch_forces_n=(10.0, -5.0))
    with pytest.raises(ProfileError, match="repeats"):
        Procedure(repeats=0)
    with pytest.raises(ProfileError, match="sample_rate_hz"):
        Instrument(sample_rate_hz=0.0)


def test_b_without_c_is_rejected() -> None:
    with pytest.raises(ProfileError, match="c_s_per_mm"):
        DriveUnderTest(roller_id="x", k_s_n=1.0, k_inf_per_n=0.003, a_per_n=0.002,
                       b_per_n=0.001, c_s_per_mm=0.0, max_force_coeffs=(0.0, 1.0, 0.0))
