"""The integrator against the analytic responses of the lag [001 Eqs. 10–15, 002]."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest

from flowtwin.dynamics import DynamicsResult, ExtrusionParams, integrate
from flowtwin.errors import DataError, ProfileError


def ser(res: DynamicsResult) -> npt.NDArray[np.void]:
    """The time series of a result that was asked for one."""
    assert res.series is not None
    return res.series


K = 0.06  # s, Tronvoll's lag factor at 0.2 mm layers [001 Table II]
KC = 0.01  # mm/N column compliance (a plausible magnitude; not from a seed)


def params(n: int = 1, **kw: object) -> ExtrusionParams:
    base: dict[str, object] = {"lag_k_s": K, "compliance_mm_per_n": KC}
    base.update(kw)
    return ExtrusionParams.build(n, **base)  # type: ignore[arg-type]


def test_series_records_are_the_kernels_sample_columns() -> None:
    """The integrator views the kernel's sample rows as the series' records: the fields of
    ``SERIES_DTYPE`` must be the columns ``S_T … S_X`` of ``_acc_kernel``, in that order,
    eight bytes each."""
    from flowtwin.dynamics import _acc_kernel as acc
    from flowtwin.dynamics.extrusion_result import SERIES_DTYPE

    columns = {"t_s": acc.S_T, "e_cmd_mm": acc.S_E, "v_cmd_mm_s": acc.S_VCMD,
               "v_fil_mm_s": acc.S_VFIL, "q_out_mm3_s": acc.S_Q, "feed_force_n": acc.S_F,
               "slip": acc.S_SLIP, "compression_mm": acc.S_X}
    assert SERIES_DTYPE.names == tuple(columns)
    fields = SERIES_DTYPE.fields
    assert fields is not None
    assert [fields[f][1] for f in columns] == [8 * c for c in columns.values()]
    assert SERIES_DTYPE.itemsize == 8 * acc.N_SER


def test_step_response_is_first_order_lag(make_feed):
    # H(s) = 1/(1 + Ks) [001 Eq. 15]: a step v0 gives v_out = v0 (1 - exp(-t/K)) [002].
    v0 = 3.0
    feed = make_feed([0.5], [[v0]])
    p = params()
    res = integrate(feed, p, series_dt_s=0.001)
    t = ser(res)["t_s"]
    exact = p.filament_area_mm2 * v0 * (1.0 - np.exp(-t / K))
    rel = np.abs(ser(res)["q_out_mm3_s"] - exact) / (p.filament_area_mm2 * v0)
    assert rel.max() <= 1e-6
    # melt out over the move: v0 (T - K (1 - e^{-T/K})) mm of filament
    t_end = 0.5
    out = p.filament_area_mm2 * v0 * (t_end - K * (1.0 - math.exp(-t_end / K)))
    assert res.moves["out_mm3"][0] == pytest.approx(out, rel=1e-6)


def test_ramp_response(make_feed):
    # v_in = a t  ->  v_out = a (t - K (1 - e^{-t/K}))
    a = 40.0
    feed = make_feed([0.3], [[0.0, a]])
    res = integrate(feed, params(), series_dt_s=0.0005)
    t = ser(res)["t_s"]
    exact = a * (t - K * (1.0 - np.exp(-t / K)))
    q = ser(res)["q_out_mm3_s"] / params().filament_area_mm2
    mask = t > 0.01  # relative error needs a non-vanishing reference
    assert np.max(np.abs(q[mask] - exact[mask]) / exact[mask]) <= 1e-6
    assert np.max(np.abs(q - exact)) <= 1e-9 * a * 0.3


def test_cubic_input_against_closed_form(make_feed):
    # v_in = c3 t³: particular solution K(c3 t³ - 3K c3 t² + 6K² c3 t - 6K³ c3) + C e^{-t/K}
    c3 = 500.0
    feed = make_feed([0.25], [[0.0, 0.0, 0.0, c3]])
    res = integrate(feed, params(), series_dt_s=0.001)
    t = ser(res)["t_s"]
    xp = K * c3 * (t**3 - 3 * K * t**2 + 6 * K**2 * t - 6 * K**3)
    x = xp + 6 * K**4 * c3 * np.exp(-t / K)
    mask = t > 0.02
    rel = np.abs(ser(res)["compression_mm"][mask] - x[mask]) / x[mask]
    assert rel.max() <= 1e-6


def test_impulse_response(make_feed):
    # An impulse of E mm of filament puts Δl = E at once; output (E/K) e^{-t/K} [002].
    e_imp = 0.2
    feed = make_feed([0.4], [[0.0]])
    res = integrate(feed, params(), initial_compression_mm=e_imp, series_dt_s=0.001)
    t = ser(res)["t_s"]
    exact = e_imp / K * np.exp(-t / K)
    q = ser(res)["q_out_mm3_s"] / params().filament_area_mm2
    assert np.max(np.abs(q - exact) / exact) <= 1e-6


def test_short_pulse_converges_to_impulse(make_feed):
    # A pulse of area E and width w tends to the impulse response as w -> 0 (error O(w/K)).
    e_imp = 0.2
    t_probe = 0.1
    errs = []
    for w in (1e-3, 1e-4, 1e-5):
        feed = make_feed([w, 0.2], [[e_imp / w], [0.0]])
        res = integrate(feed, params(2), series_window_s=(t_probe, t_probe), series_dt_s=1.0)
        q = ser(res)["q_out_mm3_s"][0] / params().filament_area_mm2
        errs.append(abs(q - e_imp / K * math.exp(-t_probe / K)) / (e_imp / K))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-3


def test_step_plus_scaled_impulse_gives_rectangular_output(make_feed):
    # [002]: step + impulse of K·v0 -> output jumps straight to v0 and stays there.
    v0 = 2.5
    feed = make_feed([0.3], [[v0]])
    res = integrate(feed, params(), initial_compression_mm=K * v0, series_dt_s=0.001)
    q = ser(res)["q_out_mm3_s"] / params().filament_area_mm2
    assert np.max(np.abs(q - v0)) <= 1e-12 * v0


def test_linear_advance_with_k_equal_lag_restores_command(make_feed):
    # [001 Eq. 11]: v_in = v0 + K dv0/dt with K_LA = K gives v_out = v0 exactly.
    acc = 120.0
    ta, tc = 0.05, 0.2
    vc = acc * ta
    # accel, cruise, decel (each with the K·a speed offset), then rest
    feed = make_feed([ta, tc, ta, 0.3],
                     [[K * acc, acc], [vc], [vc - K * acc, -acc], [0.0]])
    res = integrate(feed, params(4), series_dt_s=0.0005)
    t = ser(res)["t_s"]
    v_nominal = np.interp(t, [0, ta, ta + tc, 2 * ta + tc, 1.0], [0, vc, vc, 0, 0])
    q = ser(res)["q_out_mm3_s"] / params().filament_area_mm2
    assert np.max(np.abs(q - v_nominal)) <= 1e-9 * vc
    # no ooze after the stop: the column is relaxed when the command ends
    assert abs(res.final_compression_mm) <= 1e-12


def test_no_backflow_and_retraction_gap(make_feed):
    # extrude, then retract 2 mm fast, hold, then prime 2 mm and extrude again
    feed = make_feed([0.3, 0.05, 0.2, 0.05, 0.3],
                     [[4.0], [-40.0], [0.0], [40.0], [4.0]])
    res = integrate(feed, params(5), series_dt_s=0.0005)
    s = ser(res)
    assert np.all(s["q_out_mm3_s"] >= 0.0)  # never negative [001 Fig. 8]
    during_hold = (s["t_s"] > 0.36) & (s["t_s"] < 0.55)
    assert np.all(s["compression_mm"][during_hold] < 0.0)  # filament pulled off the melt
    assert np.all(s["q_out_mm3_s"][during_hold] == 0.0)
    assert np.all(s["feed_force_n"][during_hold] == 0.0)
    # Δl at the end of the retraction: decays to zero crossing, then pure retraction
    x_before = 4.0 * K * (1 - math.exp(-0.3 / K))
    assert s["compression_mm"][during_hold][0] == pytest.approx(x_before - 2.0, abs=0.02)
    assert res.summary.n_events >= 2  # down through 0 while retracting, up again on prime


def test_segmentation_does_not_change_the_exact_solution(make_feed):
    # no internal step: splitting the same input into 50 pieces gives the same state
    v0, a = 1.0, 30.0
    one = integrate(make_feed([0.2], [[v0, a]]), params())
    dts = np.full(50, 0.2 / 50)
    starts = np.arange(50) * 0.2 / 50
    many_feed = make_feed(dts, [[v0 + a * s, a] for s in starts])
    many = integrate(many_feed, params(50))
    assert many.final_compression_mm == pytest.approx(one.final_compression_mm, rel=1e-13)
    assert many.summary.out_mm3 == pytest.approx(one.summary.out_mm3, rel=1e-13)


def test_slip_constant_gradient_matches_exponential(make_feed):
    # constant v, s' constant [000 Eq. 6]: x' = v(1-kp) - (1/K + v s'/k) x, exact exponential
    v, kp, sp = 5.0, 0.02, 0.0032
    feed = make_feed([0.4], [[v]])
    p = params(slip_offset=kp, slip_gradient_per_n=sp)
    res = integrate(feed, p, series_dt_s=0.002)
    beta = 1.0 / K + v * sp / KC
    x_inf = v * (1.0 - kp) / beta
    t = ser(res)["t_s"]
    x = x_inf * (1.0 - np.exp(-beta * t))
    mask = t > 0.005
    assert np.max(np.abs(ser(res)["compression_mm"][mask] - x[mask]) / x[mask]) <= 1e-10
    # slip at the end equals k_p + s' F_f [000 Eq. 6]
    f_end = x_inf * (1.0 - math.exp(-beta * 0.4)) / KC
    assert ser(res)["slip"][-2] == pytest.approx(kp + sp * ser(res)["feed_force_n"][-2],
                                                   rel=1e-12)
    assert res.moves["peak_force_n"][0] == pytest.approx(f_end, rel=1e-9)


def test_velocity_dependent_slip_steady_state(make_feed):
    # [000 Eq. 8]: s' = a + b exp(-c v) at the feed speed; steady state x = v(1-kp)/β
    v, a, b, c = 2.0, 0.003, 0.004, 0.5
    feed = make_feed([2.0], [[v]])
    p = params(slip_gradient_per_n=a, slip_velocity_gain_per_n=b, slip_velocity_decay_s_per_mm=c)
    res = integrate(feed, p)
    sp = a + b * math.exp(-c * v)
    x_inf = v / (1.0 / K + v * sp / KC)
    assert res.final_compression_mm == pytest.approx(x_inf, rel=1e-12)


def test_slip_results_independent_of_internal_step(make_feed, rng):
    n = 40
    dts = rng.uniform(0.01, 0.2, n)
    coef = [[rng.uniform(-1, 8), rng.uniform(-200, 200), rng.uniform(-500, 500)]
            for _ in range(n)]
    feed = make_feed(dts, coef)
    p = params(n, slip_offset=0.01, slip_gradient_per_n=0.003, slip_velocity_gain_per_n=0.002,
               slip_velocity_decay_s_per_mm=0.3)
    a = integrate(feed, p, stiffness=1.0)
    b = integrate(feed, p, stiffness=0.5)
    for name in ("out_mm3", "fed_mm3", "slip_loss_mm3"):
        ref = np.abs(a.moves[name]).max()
        assert np.max(np.abs(a.moves[name] - b.moves[name])) <= 1e-9 * ref
    assert b.final_compression_mm == pytest.approx(a.final_compression_mm, rel=1e-9, abs=1e-15)


def test_mass_conservation_random_feed(make_feed, rng):
    # filament in = melt out + stored compression, to 1e-9 of the total
    n = 300
    dts = rng.uniform(0.002, 0.3, n)
    coef = [[rng.uniform(-20, 10), rng.uniform(-400, 400), rng.uniform(-900, 900),
             rng.uniform(-5000, 5000)] for _ in range(n)]
    feed = make_feed(dts, coef)
    p = params(n, slip_offset=0.01, slip_gradient_per_n=0.003, max_feed_force_n=25.0)
    res = integrate(feed, p, initial_compression_mm=0.05)
    s = res.summary
    total = abs(s.fed_mm3) + s.out_mm3
    assert abs(s.mass_balance_error_mm3) <= 1e-9 * total
    # command = fed + slip loss + grinding loss
    assert s.fed_cmd_mm3 == pytest.approx(s.fed_mm3 + s.slip_loss_mm3 + s.grind_loss_mm3,
                                          abs=1e-9 * total)
    # per-move sums add up to the totals
    per = np.sum(res.moves["out_mm3"] + res.moves["stop_out_mm3"])
    assert per + res.before_first_move["stop_out_mm3"][0] == pytest.approx(s.out_mm3, rel=1e-12)


def test_constant_parameters_as_views_or_arrays_give_identical_results(make_feed, rng):
    # a float becomes a stride-0 view that the kernel reads as one value; the same values
    # spelled out per move must give the same bits (also with a per-move lag next to them)
    n = 400
    dts = rng.uniform(0.002, 0.2, n)
    coef = [[rng.uniform(-20, 10), rng.uniform(-400, 400), rng.uniform(-900, 900),
             rng.uniform(-5000, 5000)] for _ in range(n)]
    feed = make_feed(dts, coef)
    lag = rng.uniform(0.02, 0.2, n)
    scal = {"compliance_mm_per_n": KC, "slip_offset": 0.01, "slip_gradient_per_n": 0.003,
            "slip_velocity_gain_per_n": 0.002, "slip_velocity_decay_s_per_mm": 0.1,
            "max_feed_force_n": 5.0}
    a = integrate(feed, params(n, lag_k_s=lag, **scal), initial_compression_mm=0.05)
    full = {k: np.full(n, v) for k, v in scal.items()}
    b = integrate(feed, params(n, lag_k_s=lag, **full), initial_compression_mm=0.05)
    assert params(n, **scal).slip_offset.strides == (0,)
    assert a.moves.tobytes() == b.moves.tobytes()
    assert a.summary == b.summary
    assert a.summary.grinding_moves > 0 and a.summary.n_events > 0  # the limits were used


def test_mass_conservation_without_slip_is_independent_of_bookkeeping(make_feed, rng):
    # no slip: melt out comes from the φ-function integral, not from the balance
    n = 200
    dts = rng.uniform(0.001, 0.5, n)
    coef = [[rng.uniform(-5, 10), rng.uniform(-300, 300), rng.uniform(-100, 100),
             rng.uniform(-1000, 1000)] for _ in range(n)]
    res = integrate(make_feed(dts, coef), params(n, lag_k_s=rng.uniform(0.01, 2.0, n)))
    s = res.summary
    assert abs(s.mass_balance_error_mm3) <= 1e-9 * (abs(s.fed_mm3) + s.out_mm3)


def test_grinding_sawtooth(make_feed):
    # force limit below the steady force: grind at F_max, decay to (1-f) F_max, resume
    v, fmax, frac = 5.0, 20.0, 0.2
    feed = make_feed([1.0], [[v]])
    p = params(max_feed_force_n=fmax, grind_release_fraction=frac)
    res = integrate(feed, p, series_dt_s=0.0002)
    s = ser(res)
    assert s["feed_force_n"].max() <= fmax * (1 + 1e-12)
    assert res.moves["grinding"][0]
    assert res.moves["grind_loss_mm3"][0] > 0.0
    # analytic cycle: decay thr -> rel takes K ln(1/(1-f)); rise rel -> thr with input v
    thr = KC * fmax
    rel = (1 - frac) * thr
    t_first = -K * math.log(1 - thr / (K * v))
    t_decay = K * math.log(1 / (1 - frac))
    t_rise = K * math.log((K * v - rel) / (K * v - thr))
    n_cycles = (1.0 - t_first) / (t_decay + t_rise)
    events = res.summary.n_events
    assert abs(events - 2 * n_cycles) <= 2
    # filament lost while grinding = commanded filament during the grinding time
    grind_time = (events // 2) * t_decay
    assert res.moves["grind_loss_mm3"][0] == pytest.approx(
        p.filament_area_mm2 * v * grind_time, rel=0.1)


def test_temperature_dependent_lag_callable(make_feed):
    # K(T) computed upstream from the temperature per move
    feed = make_feed([0.2, 0.2], [[2.0], [2.0]])
    temps = np.array([200.0, 230.0])
    p = ExtrusionParams.build(2, lag_k_s=lambda t: 0.06 * np.exp(-0.02 * (t - 200.0)),
                              compliance_mm_per_n=KC, temperature_c=temps)
    assert p.lag_k_s[1] == pytest.approx(0.06 * math.exp(-0.6))
    res = integrate(feed, p)
    assert res.summary.mass_balance_error_mm3 == pytest.approx(0.0, abs=1e-12)


def test_errors_name_the_field(make_feed):
    feed = make_feed([0.1], [[1.0]])
    with pytest.raises(ProfileError, match=r"params\.n_moves"):
        integrate(feed, params(2))
    with pytest.raises(ProfileError, match="lag_k_s"):
        params(lag_k_s=0.0)
    with pytest.raises(ProfileError, match="move 1"):
        params(2, compliance_mm_per_n=[0.01, -1.0])
    with pytest.raises(DataError, match="series_dt_s"):
        integrate(feed, params(), series_dt_s=0.0)
    with pytest.raises(ProfileError, match="temperature"):
        params(lag_k_s=lambda t: t)


def test_steady_slip_matches_the_drive_model(make_feed):
    # at constant feed the integrator must settle at s = (k_p + s'F_0)/(1 + s'F_0), F_0 = K v/k
    # (flowtwin.physics.drive.steady_state_slip, from [000 Eq. 6] with F_f = F_0 (1 - s))
    from flowtwin.physics.drive import steady_state_slip

    v, kp, sp = 6.0, 0.015, 0.0032
    res = integrate(make_feed([3.0], [[v]]),
                    params(slip_offset=kp, slip_gradient_per_n=sp), series_dt_s=0.5)
    s_expected = float(steady_state_slip(K * v / KC, sp, k_p=kp))
    assert ser(res)["slip"][-2] == pytest.approx(s_expected, rel=1e-12)
    assert ser(res)["v_fil_mm_s"][-2] == pytest.approx(v * (1 - s_expected), rel=1e-12)


def test_series_follows_the_feed(make_feed, rng):
    n = 20
    dts = rng.uniform(0.01, 0.1, n)
    coef = [[rng.uniform(-3, 6), rng.uniform(-50, 50), rng.uniform(-300, 300),
             rng.uniform(-2000, 2000)] for _ in range(n)]
    feed = make_feed(dts, coef)
    res = integrate(feed, params(n), series_dt_s=0.003, tail_s=0.1)
    s = ser(res)
    inside = s["t_s"] < feed.t_end_s
    np.testing.assert_allclose(s["e_cmd_mm"][inside], feed.position_at(s["t_s"][inside]),
                               atol=1e-12)
    np.testing.assert_allclose(s["v_cmd_mm_s"][inside], feed.velocity_at(s["t_s"][inside]),
                               atol=1e-12)
    # during the tail the column relaxes: q = A x / K
    tail = ~inside
    a = params().filament_area_mm2
    np.testing.assert_allclose(s["q_out_mm3_s"][tail],
                               a * np.maximum(s["compression_mm"][tail], 0) / K, rtol=1e-12)


def test_starting_above_the_force_limit_grinds_until_released(make_feed):
    # Δl0/k = 30 N > 20 N: no feeding until the force decays to 16 N, after K ln(30/16)
    feed = make_feed([0.2], [[1.0]])
    p = params(max_feed_force_n=20.0, grind_release_fraction=0.2)
    res = integrate(feed, p, initial_compression_mm=30.0 * KC, series_dt_s=0.001)
    s = ser(res)
    t_release = K * math.log(30.0 / 16.0)
    before = s["t_s"] < t_release - 1e-3
    assert np.all(s["v_fil_mm_s"][before] == 0.0)
    assert res.moves["grinding"][0]
    assert res.moves["grind_loss_mm3"][0] == pytest.approx(p.filament_area_mm2 * t_release,
                                                           rel=1e-9)
    assert res.summary.as_dict()["grinding_moves"] == 1


def test_inconsistent_inputs_are_refused(make_feed):
    feed = make_feed([0.1, 0.1], [[1.0], [1.0]])
    bad = type(feed)(t0_s=feed.t0_s, dt_s=feed.dt_s, coef=feed.coef, e0_mm=feed.e0_mm,
                     move=np.array([0, 5]), gap=feed.gap, phase=feed.phase,
                     move_t0_s=feed.move_t0_s, move_t1_s=feed.move_t1_s,
                     move_de_mm=feed.move_de_mm)
    with pytest.raises(DataError, match="inconsistent"):
        integrate(bad, params(2))
    p = params(2)
    with pytest.raises(ProfileError, match="slip_offset"):
        type(p)(p.lag_k_s, p.compliance_mm_per_n, p.slip_offset[:1], p.slip_gradient_per_n,
                p.slip_velocity_gain_per_n, p.slip_velocity_decay_s_per_mm,
                p.max_feed_force_n, p.filament_area_mm2)


def test_adaptive_stage_count_matches_the_fixed_6_stage_method(make_feed, rng):
    # the fewest-stage choice (bound C_s z^(2s+1) <= 1e-16 per substep) against the fixed
    # 6-stage method on cubic feeds with retractions, velocity-dependent slip [000 Eq. 8] and
    # grinding: per-move volumes agree to 1e-10 of the largest (the bound summed over a
    # few thousand substeps, with margin for the events located on slightly different paths)
    from flowtwin.dynamics.integrator import _integrate

    n = 400
    dts = rng.uniform(0.001, 0.2, n)
    coef = [[rng.uniform(-2, 12), rng.uniform(-300, 300), rng.uniform(-900, 900),
             rng.uniform(-5000, 5000)] for _ in range(n)]
    feed = make_feed(dts, coef)
    p = params(n, slip_offset=0.01, slip_gradient_per_n=0.0024,
               slip_velocity_gain_per_n=0.0018, slip_velocity_decay_s_per_mm=0.32,
               max_feed_force_n=25.0)
    kw: dict[str, object] = {"initial_compression_mm": 0.0, "initially_grinding": False,
                             "tail_s": 0.2, "series_dt_s": None, "series_window_s": None,
                             "stiffness": 1.0}
    fast = _integrate(feed, p, min_stages=2, **kw)  # type: ignore[arg-type]
    ref = _integrate(feed, p, min_stages=6, **kw)  # type: ignore[arg-type]
    assert fast.summary.grinding_moves > 0  # the test covers grinding events
    for name in ("fed_mm3", "out_mm3", "stop_out_mm3", "slip_loss_mm3", "grind_loss_mm3",
                 "peak_force_n", "q_max_mm3_s"):
        scale = float(np.max(np.abs(ref.moves[name]))) or 1.0
        assert np.max(np.abs(fast.moves[name] - ref.moves[name])) <= 1e-10 * scale, name
    assert fast.final_compression_mm == pytest.approx(ref.final_compression_mm, rel=1e-10)


def test_constant_speed_slip_is_the_exact_exponential_over_long_segments(make_feed):
    # a cruise of 50 time constants with velocity-dependent slip: β = 1/K + v s'(v)/k is
    # constant, x(t) = x∞ (1 - e^{-βt}), ∫x = x∞ (t - (1 - e^{-βt})/β) in closed form
    v, kp, a, b, c = 3.0, 0.01, 0.0024, 0.0018, 0.32
    t = 50 * K
    p = params(slip_offset=kp, slip_gradient_per_n=a, slip_velocity_gain_per_n=b,
               slip_velocity_decay_s_per_mm=c)
    res = integrate(make_feed([t], [[v]]), p)
    sp = a + b * math.exp(-c * v)
    beta = 1.0 / K + v * sp / KC
    x_inf = v * (1.0 - kp) / beta
    x_end = x_inf * (1.0 - math.exp(-beta * t))
    ix = x_inf * (t - (1.0 - math.exp(-beta * t)) / beta)
    assert res.final_compression_mm == pytest.approx(x_end, rel=1e-13)
    area = p.filament_area_mm2
    assert res.moves["out_mm3"][0] == pytest.approx(area * ix / K, rel=1e-13)
    assert res.moves["slip_loss_mm3"][0] == pytest.approx(
        area * (kp * v * t + v * sp / KC * ix), rel=1e-13)


def _hand_feed(dt: npt.NDArray[np.float64], v: npt.NDArray[np.float64],
               move: npt.NDArray[np.int64], gap: npt.NDArray[np.bool_], n_moves: int):
    """A feed of constant-speed segments with the given owners (moves without segments
    allowed: they get a zero-length span at the time the next segment starts)."""
    from flowtwin.dynamics import CommandedFeed

    t0 = np.concatenate(([0.0], np.cumsum(dt)[:-1]))
    e0 = np.concatenate(([0.0], np.cumsum(dt * v)[:-1]))
    coef = np.zeros((dt.size, 4))
    coef[:, 0] = v
    mt0 = np.zeros(n_moves)
    mt1 = np.zeros(n_moves)
    de = np.zeros(n_moves)
    t_next = t0[-1] + dt[-1]
    for i in range(n_moves - 1, -1, -1):
        own = np.flatnonzero((move == i) & ~gap)
        if own.size:
            mt0[i], mt1[i] = t0[own[0]], t0[own[-1]] + dt[own[-1]]
            de[i] = float(np.sum(dt[own] * v[own]))
        else:
            mt0[i] = mt1[i] = t_next
        t_next = mt0[i]
    return CommandedFeed(t0_s=t0, dt_s=dt, coef=coef, e0_mm=e0, move=move, gap=gap,
                         phase=np.zeros(dt.size, dtype=np.int8), move_t0_s=mt0, move_t1_s=mt1,
                         move_de_mm=de)


def test_per_move_bookkeeping_over_many_moves_against_the_closed_form(rng):
    # 900 moves (several of the kernel's 256-move buffers), some split into two segments,
    # some without segments, stops after some (and a rest before the first move); no slip
    # and a positive column throughout, so each segment is x' = v - x/K exactly:
    # x1 = vK + (x0 - vK) e^(-dt/K) [001 Eq. 10] and the melt out is v dt - (x1 - x0)
    # (filament in = out + stored). The reference is accumulated here per move and stop.
    n = 900
    owners: list[tuple[int, bool]] = [(-1, True)]
    for i in range(n):
        if rng.uniform() < 0.05:
            continue  # no segment: a move of zero duration
        owners += [(i, False)] * (2 if rng.uniform() < 0.3 else 1)
        if rng.uniform() < 0.2:
            owners.append((i, True))
    move = np.array([o[0] for o in owners], dtype=np.int64)
    gap = np.array([o[1] for o in owners], dtype=bool)
    dt = rng.uniform(0.005, 0.2, move.size)
    v = np.where(gap, 0.0, rng.uniform(0.5, 8.0, move.size))
    k_s = 0.05
    feed = _hand_feed(dt, v, move, gap, n)
    x0 = 0.2
    res = integrate(feed, params(n, lag_k_s=k_s), initial_compression_mm=x0)
    area = params().filament_area_mm2
    out_move = np.zeros(n)
    out_stop = np.zeros(n)
    out_pre = 0.0
    x = x0
    for j in range(move.size):
        x1 = v[j] * k_s + (x - v[j] * k_s) * math.exp(-dt[j] / k_s)
        out = v[j] * dt[j] - (x1 - x)
        if move[j] < 0:
            out_pre += out
        elif gap[j]:
            out_stop[move[j]] += out
        else:
            out_move[move[j]] += out
        x = x1
    # the kernel's φ-series and exponentials against math.exp: rounding of a few
    # operations per segment, far below 1e-11 of each move's output
    m = res.moves
    assert np.allclose(m["out_mm3"], area * out_move, rtol=1e-11, atol=1e-15)
    assert np.allclose(m["stop_out_mm3"], area * out_stop, rtol=1e-11, atol=1e-15)
    assert res.before_first_move["stop_out_mm3"][0] == pytest.approx(area * out_pre,
                                                                      rel=1e-11)
    has = np.zeros(n, dtype=bool)
    has[move[~gap]] = True
    assert np.all(m["duration_s"][~has] == 0.0) and np.all(m["out_mm3"][~has] == 0.0)
    assert np.allclose(m["duration_s"], feed.move_t1_s - feed.move_t0_s, rtol=0, atol=0)
    assert np.allclose(m["fed_mm3"], area * feed.move_de_mm, rtol=1e-13, atol=0)
    # a stopping move's ooze is its stop; a move without E oozes its own output as well
    assert np.array_equal(m["ooze_mm3"], np.where(feed.move_de_mm > 0.0, m["stop_out_mm3"],
                                                  m["out_mm3"] + m["stop_out_mm3"]))
    assert res.final_compression_mm == pytest.approx(x, rel=1e-12)
    total = area * (out_move.sum() + out_stop.sum() + out_pre)
    assert res.summary.out_mm3 == pytest.approx(total, rel=1e-12)


def test_feed_out_of_move_order_is_refused(make_feed):
    # the kernel writes each move's results when the next one starts: a feed whose
    # segments go back to an earlier move (or a stop before its move) is refused
    feed = make_feed([0.1, 0.1, 0.1], [[1.0], [1.0], [1.0]])
    for move, gap in (([0, 1, 0], [False, False, False]), ([0, 1, 1], [False, True, False])):
        bad = type(feed)(t0_s=feed.t0_s, dt_s=feed.dt_s, coef=feed.coef, e0_mm=feed.e0_mm,
                         move=np.array(move), gap=np.array(gap), phase=feed.phase,
                         move_t0_s=feed.move_t0_s, move_t1_s=feed.move_t1_s,
                         move_de_mm=feed.move_de_mm)
        with pytest.raises(DataError, match="move order"):
            integrate(bad, params(3))
