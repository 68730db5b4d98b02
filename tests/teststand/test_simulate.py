"""The virtual stand runs the procedure of [000 §3] with the paper's instrument noise."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.errors import ProfileError
from flowtwin.profiles import load_rollers
from flowtwin.teststand import (
    DriveUnderTest,
    Instrument,
    Procedure,
    SlipLaw,
    simulate_campaign,
    simulate_record,
)

ROLLERS = load_rollers()
K_P = 0.0063


def _record(number: int = 3, fp: float = 80.0, v: float = 1.0, seed: int = 0,
            **drive_kw: float):
    drive = DriveUnderTest.from_roller(ROLLERS[number], law=SlipLaw.PINCH, k_p=K_P,
                                       **drive_kw)  # type: ignore[arg-type]
    rec = simulate_record(drive, pinch_force_n=fp, speed_mm_s=v, repeat=0,
                          rng=np.random.default_rng(seed))
    return drive, rec


def test_sampling_ramp_release_and_wait() -> None:
    drive, rec = _record()
    dt = np.diff(rec.t_s)
    np.testing.assert_allclose(dt, 1.0 / 50.0, rtol=1e-9)  # 50 samples/s
    fmax = float(drive.max_feed_force_n(80.0))  # 90.5 N [000 Fig. 6]
    i = int(np.argmax(rec.feed_force_n))
    # loading: feed force rises at 4 N/s; least squares over the loading phase, where the
    # 1 N noise over ~1100 samples gives a slope error of ~0.001 N/s
    slope = np.polyfit(rec.t_s[:i], rec.feed_force_n[:i], 1)[0]
    assert slope == pytest.approx(4.0, abs=0.01)
    # the ramp ends near the maximum feed force of Fig. 6 (within the 1 N noise, 3 sigma + max)
    assert rec.t_s[i] == pytest.approx(fmax / 4.0, abs=0.3)
    # the record ends with 5 s of waiting at zero force, the filament moving freely
    tail = rec.t_s > rec.t_s[-1] - 5.0 + 0.02
    assert tail.sum() == pytest.approx(250, abs=1)
    assert abs(float(rec.feed_force_n[tail].mean())) < 4 * 1.0 / np.sqrt(tail.sum())
    # during the wait: s = k_p, so v = v_nom·(1 - k_p); noise 0.025 mm/s, 4 sigma of the mean
    assert float(rec.filament_speed_mm_s[tail].mean()) == pytest.approx(
        1.0 - K_P, abs=4 * 0.025 / np.sqrt(tail.sum()))


def test_instrument_noise_levels() -> None:
    _, rec = _record(seed=3)
    tail = rec.t_s > rec.t_s[-1] - 4.9
    # a standard deviation from n samples has a relative error of 1/sqrt(2n): 4.5 % for the
    # ~245 wait samples (±20 % = 4.4 sigma), 1.8 % for the ~1500 pinch samples (±10 %)
    assert float(rec.feed_force_n[tail].std()) == pytest.approx(1.0, rel=0.2)
    assert float(rec.filament_speed_mm_s[tail].std()) == pytest.approx(0.025, rel=0.2)
    assert float(rec.pinch_force_n.mean()) == pytest.approx(80.0, abs=0.1)
    assert float(rec.pinch_force_n.std()) == pytest.approx(1.0, rel=0.1)


def test_stall_is_detected_on_the_measured_speed() -> None:
    _, rec = _record()
    i = int(np.argmax(rec.feed_force_n))
    after = rec.filament_speed_mm_s[i:]
    # the ramp stops at the first measured speed below 0.05 mm/s after the failure
    first_low = int(np.argmax(after < 0.05))
    assert first_low <= 10  # a few samples at most: true speed 0, noise 0.025 mm/s
    # before the failure the filament moves at v(1 - s) with s up to ~30 %
    assert float(rec.filament_speed_mm_s[:i].min()) > 0.4


def test_slip_grows_linearly_with_force() -> None:
    drive, rec = _record(v=15.0)
    i = int(np.argmax(rec.feed_force_n))
    slip = 1.0 - rec.filament_speed_mm_s[:i] / 15.0
    gradient = float(drive.slip_gradient_per_n(80.0, 15.0))
    # slip at the maximum feed force: "slip can reach ~30 % before failure" [000 §5]
    assert K_P + gradient * float(drive.max_feed_force_n(80.0)) == pytest.approx(0.309,
                                                                                 abs=0.001)
    resid = slip - (K_P + gradient * rec.feed_force_n[:i])
    # residual = speed noise/15 - gradient·force noise: sigma ≈ sqrt(0.0017² + 0.0034²)
    assert float(resid.std()) < 0.005


def test_full_slip_before_failure_for_the_plain_roller() -> None:
    """Roller #4 at 150 N: Eq. 6 reaches 100 % slip (55 N·2.08 %/N) before its maximum
    force of Fig. 7 (55 N), so the record stalls by slip: the maximum recorded force is where
    the measured speed falls below 0.05 mm/s."""
    drive, rec = _record(number=4, fp=150.0, v=0.5)
    gradient = float(drive.slip_gradient_per_n(150.0, 0.5))
    stall_force = (1.0 - K_P - 0.05 / 0.5) / gradient  # s = 1 - 0.05/0.5
    assert float(rec.feed_force_n.max()) < float(drive.max_feed_force_n(150.0))
    assert float(rec.feed_force_n.max()) == pytest.approx(stall_force, abs=5.0)


def test_seed_reproduces_and_differs() -> None:
    drive = DriveUnderTest.from_roller(ROLLERS[2], law=SlipLaw.COMBINED, k_p=K_P,
                                       max_force_scatter=0.08)
    proc = Procedure(pinch_forces_n=(40.0, 100.0), speeds_mm_s=(1.0, 10.0), repeats=2)
    a = simulate_campaign(drive, seed=5, procedure=proc)
    b = simulate_campaign(drive, seed=5, procedure=proc)
    c = simulate_campaign(drive, seed=6, procedure=proc)
    assert len(a) == 2 * 2 * 2
    assert [r.key for r in a] == [r.key for r in b]
    assert all(np.array_equal(x.feed_force_n, y.feed_force_n) for x, y in zip(a, b, strict=True))
    assert not np.array_equal(a[0].feed_force_n[:100], c[0].feed_force_n[:100])
    # the paper's loop order: pinch force outer, speed inner, repeats innermost
    assert [(r.key.pinch_force_set_n, r.key.nominal_speed_mm_s, r.key.repeat) for r in a][:3] \
        == [(40.0, 1.0, 0), (40.0, 1.0, 1), (40.0, 10.0, 0)]


def test_max_force_scatter_is_relative() -> None:
    drive = DriveUnderTest.from_roller(ROLLERS[7], law=SlipLaw.PINCH, k_p=K_P,
                                       max_force_scatter=0.08)
    proc = Procedure(pinch_forces_n=(100.0,), speeds_mm_s=(10.0,), repeats=60)
    recs = simulate_campaign(drive, seed=11, procedure=proc)
    peaks = np.array([r.feed_force_n.max() for r in recs])
    trend = float(drive.max_feed_force_n(100.0))
    # sd of 60 peaks: 8 % of the trend (≈ 7 N) plus ~1 N of load-cell noise; ±30 % covers
    # the sampling error of a standard deviation from 60 values (≈ 9 %) at > 3 sigma
    assert float(peaks.std()) == pytest.approx(0.08 * trend, rel=0.3)
    assert float(peaks.mean()) == pytest.approx(trend, abs=3 * 0.08 * trend / np.sqrt(60) + 2)


def test_pinch_crosstalk_offsets_the_feed_force() -> None:
    drive = DriveUnderTest.from_roller(ROLLERS[3], law=SlipLaw.PINCH)
    inst = Instrument(pinch_crosstalk_fraction=0.01)
    offsets = []
    for seed in range(20):
        rec = simulate_record(drive, pinch_force_n=100.0, speed_mm_s=2.0, repeat=0,
                              rng=np.random.default_rng(seed), instrument=inst)
        offsets.append(float(rec.feed_force_n[-200:].mean()))
    # uniform in ±1 % of 100 N: all within ±1 N (plus 4 sigma of a 200-sample mean)
    assert max(abs(o) for o in offsets) <= 1.0 + 4 * 1.0 / np.sqrt(200)
    assert float(np.std(offsets)) > 0.3  # it does vary (uniform ±1 N: sd 0.58 N)


def test_bad_set_points() -> None:
    drive = DriveUnderTest.from_roller(ROLLERS[3])
    with pytest.raises(ProfileError, match="pinch_force_n"):
        simulate_record(drive, pinch_force_n=0.0, speed_mm_s=1.0, repeat=0,
                        rng=np.random.default_rng(0))
    with pytest.raises(ProfileError, match="speed_mm_s"):
        simulate_record(drive, pinch_force_n=50.0, speed_mm_s=float("nan"), repeat=0,
                        rng=np.random.default_rng(0))


def test_drive_that_never_stalls_is_an_error() -> None:
    drive = DriveUnderTest(roller_id="ideal", k_s_n=0.0, k_inf_per_n=0.0,
                           max_force_coeffs=(float("1e300"), 0.0, 0.0))
    with pytest.raises(ProfileError, match="never stalls"):
        simulate_record(drive, pinch_force_n=50.0, speed_mm_s=1.0, repeat=0,
                        rng=np.random.default_rng(0))
