"""Firmware pressure advance against the published formulas and firmware documentation."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
from scipy.integrate import quad

from flowtwin.dynamics import (
    AdvanceSettings,
    DynamicsResult,
    ExtrusionParams,
    advance_eligible,
    advance_schedule,
    apply_advance,
    integrate,
    nominal_feed,
)
from flowtwin.errors import ProfileError
from flowtwin.firmware import Firmware
from flowtwin.gcode.moves import Event


def ser(res: DynamicsResult) -> npt.NDArray[np.void]:
    """The time series of a result that was asked for one."""
    assert res.series is not None
    return res.series


@pytest.fixture
def mixed_print(make_print, Move):
    """Extrusion with a non-zero junction, a retraction, a travel, an extrude-only prime."""
    moves = [Move(10, 0, de=0.4, v=60, v_end=20), Move(10, 5, de=0.3, v=40, v_end=10),
             Move(10, 5, de=-1.0, v=30), Move(20, 5, v=100), Move(20, 5, de=1.0, v=30),
             Move(30, 8, de=0.5, v=50), Move(31, 8, de=0.02, v=50)]
    return make_print(moves, accel=2000)


def _advanced_position(feed, eligible, k):
    def p(x: float) -> float:
        e = float(feed.position_at(x))
        v = float(feed.velocity_at(x))
        i = int(np.clip(np.searchsorted(feed.t0_s, x, side="right") - 1, 0,
                        feed.n_segments - 1))
        inside = feed.t_begin_s <= x < feed.t_end_s
        adv = inside and not feed.gap[i] and bool(eligible[feed.move[i]])
        return e + (k * v if adv else 0.0)
    return p


def test_klipper_matches_smoothing_integral(mixed_print):
    # Klipper docs (Kinematics.md): smooth_pa_position(t) =
    #   ∫ pa_position(x) (smooth_time/2 - |t - x|) dx / (smooth_time/2)², x in t ± smooth_time/2
    mt, tl = mixed_print
    k, st = 0.05, 0.04
    h = st / 2
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=k, smooth_time_s=st))
    p = _advanced_position(feed, advance_eligible(mt, Firmware.KLIPPER), k)
    bounds = list(np.concatenate([feed.t0_s, [feed.t_end_s]]))
    ts = np.linspace(feed.t_begin_s - 0.03, feed.t_end_s + 0.03, 70)
    for t in ts:
        pts = [b for b in bounds if t - h < b < t + h] + [t]
        kw = {"points": pts, "limit": 200, "epsabs": 1e-13, "epsrel": 1e-13}
        s = quad(lambda x, t=t: p(x) * (h - abs(t - x)), t - h, t + h, **kw)[0] / h**2
        # its derivative: (∫_t^{t+h} P - ∫_{t-h}^t P) / h²
        v = (quad(p, t, t + h, **kw)[0] - quad(p, t - h, t, **kw)[0]) / h**2
        assert float(adv.position_at(t)) == pytest.approx(s, abs=1e-11)
        assert float(adv.velocity_at(t)) == pytest.approx(v, abs=1e-9)
    # pressure advance moves filament in time, it adds none
    assert adv.e_end_mm() == pytest.approx(feed.e_end_mm(), abs=1e-12)
    seg = adv.segment_mm()
    np.testing.assert_allclose(adv.e0_mm[1:], adv.e0_mm[:-1] + seg[:-1], atol=1e-12)


def test_klipper_constant_accel_ramp(make_print, Move):
    # inside a long acceleration: smoothing a quadratic e adds a·h²/12 (second moment of the
    # triangle is h²/6) and leaves the linear K·v unchanged: S = e + K v + a h²/12, S' = v + K a
    mt, tl = make_print([Move(200, 0, de=8.0, v=150)], accel=300)
    k, st = 0.08, 0.04
    h = st / 2
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=k, smooth_time_s=st))
    r = 8.0 / 200.0
    a_e = 300.0 * r
    ts = np.linspace(0.1, 0.4, 7)  # accel phase lasts 0.5 s
    np.testing.assert_allclose(adv.velocity_at(ts), feed.velocity_at(ts) + k * a_e, atol=1e-11)
    np.testing.assert_allclose(adv.position_at(ts),
                               feed.position_at(ts) + k * feed.velocity_at(ts)
                               + a_e * h * h / 12.0, atol=1e-11)


def test_klipper_advance_only_on_xy_moves_with_increasing_e(make_print, Move):
    mt, _ = make_print([Move(10, 0, de=0.5), Move(10, 0, de=-0.5), Move(10, 0, de=0.5),
                        Move(10, 0, 1.0, de=0.2), Move(20, 0)])
    assert advance_eligible(mt, Firmware.KLIPPER).tolist() == [True, False, False, False, False]
    rrf = advance_eligible(mt, Firmware.REPRAPFIRMWARE)
    assert rrf.tolist() == [True, False, False, False, False]
    # Marlin: XYZ motion (a Z-only extruding move counts), de/D <= 3
    assert advance_eligible(mt, Firmware.MARLIN).tolist() == [True, False, False, True, False]
    mt2, _ = make_print([Move(0.1, 0, de=0.5)])
    assert not advance_eligible(mt2, Firmware.MARLIN)[0]  # e/D = 5 > 3: a prime, no advance


def test_klipper_without_advance_is_not_smoothed(mixed_print):
    mt, tl = mixed_print
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.0))
    ts = np.linspace(feed.t_begin_s, feed.t_end_s, 501)
    np.testing.assert_allclose(adv.velocity_at(ts), feed.velocity_at(ts), atol=1e-12)


def test_gcode_commands_per_firmware(mixed_print):
    mt, _ = mixed_print
    mt.events.extend([
        Event(2, 10, "SET_PRESSURE_ADVANCE", {"ADVANCE": 0.03, "SMOOTH_TIME": 0.02}),
        Event(4, 11, "M900", {"K": 0.07}),
        Event(5, 12, "M572", {"D": 0.0, "S": 0.02, "W": 0.05}),
        Event(6, 13, "M900", {"K": 12.0}),
        Event(6, 14, "SET_PRESSURE_ADVANCE", {"ADVANCE": 0.09, "EXTRUDER": "extruder1"}),
    ])
    kl = advance_schedule(mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.01))
    assert kl.k_s.tolist() == [0.01, 0.01, 0.03, 0.03, 0.03, 0.03, 0.03]
    assert kl.smooth_time_s[2] == 0.02
    assert any("M900 ignored 2x" in w for w in kl.warnings)
    ma = advance_schedule(mt, AdvanceSettings(Firmware.MARLIN))
    assert ma.k_s.tolist() == [0.0, 0.0, 0.0, 0.0, 0.07, 0.07, 0.07]
    assert any("out of range" in w for w in ma.warnings)
    rrf = advance_schedule(mt, AdvanceSettings(Firmware.REPRAPFIRMWARE))
    assert rrf.k_s.tolist() == [0, 0, 0, 0, 0, 0.02, 0.02]
    assert rrf.smooth_time_s[6] == pytest.approx(0.04)  # RRF has no smoothing window
    prusa = advance_schedule(mt, AdvanceSettings(Firmware.PRUSA))
    assert prusa.k_s[6] == 0.02 and prusa.smooth_time_s[6] == 0.05
    off = advance_schedule(mt, AdvanceSettings(Firmware.MARLIN, use_gcode=False, k_s=0.2))
    assert np.all(off.k_s == 0.2)


def test_prusa_equals_klipper_filter_with_w(mixed_print):
    mt, tl = mixed_print
    feed = nominal_feed(mt, tl)
    mt.events.append(Event(0, 1, "M572", {"S": 0.04, "W": 0.03}))
    prusa = apply_advance(feed, mt, AdvanceSettings(Firmware.PRUSA))
    klip = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.04,
                                                   smooth_time_s=0.03, use_gcode=False))
    ts = np.linspace(feed.t_begin_s - 0.02, feed.t_end_s + 0.02, 400)
    np.testing.assert_allclose(prusa.velocity_at(ts), klip.velocity_at(ts), atol=1e-12)


def test_marlin_la15_tracks_k_times_ve(make_print, Move):
    # a stop-to-stop move: advance = K·v_E throughout, speed offset K·a_E in accel/decel
    mt, tl = make_print([Move(40, 0, de=1.6, v=80)], accel=800)
    k = 0.1
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.MARLIN, k_s=k))
    ts = np.linspace(0.0, tl.end_time_s[0], 300)
    np.testing.assert_allclose(adv.position_at(ts),
                               feed.position_at(ts) + k * feed.velocity_at(ts), atol=1e-12)
    a_e = 800.0 * 1.6 / 40.0
    t_acc = 0.5 * tl.phases["accel_t"][0]
    assert float(adv.velocity_at(t_acc)) == pytest.approx(float(feed.velocity_at(t_acc))
                                                          + k * a_e)
    assert adv.e_end_mm() == pytest.approx(1.6, abs=1e-12)


def test_marlin_reaches_targets_across_a_ratio_jump(make_print, Move):
    # junction with a jump of v_E: the tracker still ends each block at K·v_E,end
    mt, tl = make_print([Move(20, 0, de=0.4, v=50, v_end=30), Move(40, 0, de=1.2, v=50)],
                        accel=1000)
    k = 0.05
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.MARLIN, k_s=k))
    t_end = tl.end_time_s[1]
    assert float(adv.position_at(t_end)) == pytest.approx(1.6, abs=1e-12)
    t_cruise = tl.phases["t_start"][1] + tl.phases["accel_t"][1] + 0.9 * tl.phases["cruise_t"][1]
    assert float(adv.position_at(t_cruise)) == pytest.approx(
        float(feed.position_at(t_cruise)) + k * float(feed.velocity_at(t_cruise)), abs=1e-12)


def test_rrf_advances_within_moves_only(make_print, Move):
    mt, tl = make_print([Move(20, 0, de=0.4, v=50, v_end=30), Move(40, 0, de=1.2, v=50)],
                        accel=1000)
    k = 0.05
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.REPRAPFIRMWARE, k_s=k))
    ts = np.linspace(0.0, tl.end_time_s[-1], 200)
    acc = np.array([feed.coef[np.clip(np.searchsorted(feed.t0_s, t, "right") - 1, 0, None), 1]
                    for t in ts])
    np.testing.assert_allclose(adv.velocity_at(ts), feed.velocity_at(ts) + k * acc, atol=1e-12)
    # the E speed jumps 0.6 -> 1.8 mm/s at the junction; that jump is never advanced
    jump = 30.0 * (1.2 / 20.0 - 0.4 / 20.0)
    assert adv.e_end_mm() - 1.6 == pytest.approx(-k * jump, abs=1e-12)


def test_linear_advance_k_equal_lag_delivers_the_command(make_print, Move):
    # Tronvoll [001]: with K_LA = K the output flow equals the commanded flow.
    lag = 0.06
    moves = [Move(30, 0, de=1.2, v=60), Move(30, 20, de=0.8, v=40), Move(60, 20, de=0.6, v=90)]
    mt, tl = make_print(moves, accel=1500)
    p = ExtrusionParams.build(3, lag_k_s=lag, compliance_mm_per_n=0.01)
    feed = nominal_feed(mt, tl)
    for fw in (Firmware.MARLIN, Firmware.REPRAPFIRMWARE):
        res = integrate(apply_advance(feed, mt, AdvanceSettings(fw, k_s=lag)), p,
                        series_dt_s=0.001)
        np.testing.assert_allclose(res.moves["out_mm3"], res.moves["cmd_mm3"], rtol=1e-9)
        q = ser(res)["q_out_mm3_s"] / p.filament_area_mm2
        np.testing.assert_allclose(q, feed.velocity_at(ser(res)["t_s"]), atol=1e-9)
        assert res.summary.ooze_mm3 == pytest.approx(0.0, abs=1e-12)
    plain = integrate(feed, p)
    klip = integrate(apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=lag)), p)
    err_plain = np.abs(plain.moves["out_mm3"] - plain.moves["cmd_mm3"]).max()
    err_klip = np.abs(klip.moves["out_mm3"] - klip.moves["cmd_mm3"]).max()
    assert err_klip < 0.1 * err_plain  # smoothing leaves a small residual


def test_apply_advance_rejects_advanced_feed(mixed_print):
    mt, tl = mixed_print
    feed = apply_advance(nominal_feed(mt, tl), mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.02))
    with pytest.raises(ProfileError, match="already carries"):
        apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.02))
    with pytest.raises(ProfileError, match="smooth_time_s"):
        AdvanceSettings(Firmware.KLIPPER, smooth_time_s=0.5)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_klipper_random_prints_conserve_filament(make_print, Move, seed):
    # random moves, junction speeds, retractions and per-move K changes: the smoothed feed is
    # continuous, commands exactly the G-code's filament, and matches the integral formula
    rng = np.random.default_rng(seed)
    moves = []
    x = y = 0.0
    speeds = rng.uniform(10, 120, 41)
    for i in range(40):
        x += rng.choice([-1, 1]) * rng.uniform(2, 8)
        y += rng.uniform(-8, 8)
        kind = rng.uniform()
        de = -rng.uniform(0.2, 1.0) if kind < 0.1 else (0.0 if kind < 0.2 else rng.uniform(0, 0.6))
        v_end = rng.uniform(0, 5) if i < 39 else 0.0
        moves.append(Move(x, y, de=de, v=float(speeds[i]), v_end=v_end))
    mt, tl = make_print(moves, accel=float(rng.uniform(500, 5000)))
    for i in range(0, 40, 7):
        adv_k = float(rng.uniform(0.01, 0.1))
        mt.events.append(Event(i, i, "SET_PRESSURE_ADVANCE", {"ADVANCE": adv_k}))
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.02))
    seg = adv.segment_mm()
    np.testing.assert_allclose(adv.e0_mm[1:], adv.e0_mm[:-1] + seg[:-1], atol=1e-10)
    assert adv.e_end_mm() == pytest.approx(feed.e_end_mm(), abs=1e-10)
    assert float(np.sum(seg)) == pytest.approx(feed.e_end_mm(), abs=1e-9)
    sched = advance_schedule(mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.02))
    h = 0.02
    k_move = sched.k_eff_s

    def p(xx: float) -> float:
        i = int(np.clip(np.searchsorted(feed.t0_s, xx, side="right") - 1, 0,
                        feed.n_segments - 1))
        inside = feed.t_begin_s <= xx < feed.t_end_s
        k = k_move[feed.move[i]] if inside and not feed.gap[i] else 0.0
        return float(feed.position_at(xx)) + k * float(feed.velocity_at(xx))

    bounds = list(np.concatenate([feed.t0_s, [feed.t_end_s]]))
    for t in rng.uniform(feed.t_begin_s, feed.t_end_s, 12):
        pts = [b for b in bounds if t - h < b < t + h] + [t]
        kw = {"points": pts, "limit": 200, "epsabs": 1e-13, "epsrel": 1e-13}
        v = (quad(p, t, t + h, **kw)[0] - quad(p, t - h, t, **kw)[0]) / h**2
        assert float(adv.velocity_at(t)) == pytest.approx(v, abs=1e-8)


def test_klipper_extruder_addressing(mixed_print):
    mt, _ = mixed_print
    mt.events.extend([Event(1, 3, "SET_PRESSURE_ADVANCE", {"ADVANCE": 0.05,
                                                           "EXTRUDER": "extruder1"}),
                      Event(2, 4, "SET_PRESSURE_ADVANCE", {"ADVANCE": 0.07,
                                                           "EXTRUDER": "extruder"})])
    t0 = advance_schedule(mt, AdvanceSettings(Firmware.KLIPPER))
    t1 = advance_schedule(mt, AdvanceSettings(Firmware.KLIPPER, tool=1))
    assert t0.k_s.tolist() == [0.0, 0.0] + [0.07] * 5
    assert t1.k_s.tolist() == [0.0] + [0.05] * 6


def test_smooth_time_change_while_moving_is_reported(make_print, Move):
    # a window change in the middle of a run of extrusions steps the averaged position
    mt, tl = make_print([Move(20, 0, de=0.8, v=60, v_end=30), Move(40, 0, de=0.8, v=60),
                         Move(40, 10), Move(60, 10, de=0.8, v=60)], accel=3000)
    mt.events.append(Event(1, 2, "SET_PRESSURE_ADVANCE", {"SMOOTH_TIME": 0.1}))
    feed = nominal_feed(mt, tl)
    adv = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.05))
    assert any("steps by" in w for w in adv.warnings)
    # a change while the extruder rests (before the third extrusion) is silent
    mt.events[-1] = Event(3, 2, "SET_PRESSURE_ADVANCE", {"SMOOTH_TIME": 0.1})
    quiet = apply_advance(feed, mt, AdvanceSettings(Firmware.KLIPPER, k_s=0.05))
    assert not any("steps by" in w for w in quiet.warnings)
    assert quiet.e_end_mm() == pytest.approx(feed.e_end_mm(), abs=1e-12)
