"""The virtual test stand: the measurement procedure of [000 §3] run on a drive model.

One record (:func:`simulate_record`), sample ``n`` at ``t = n/f_s``:

1. *Load.* The process force rises at ``r = 4 N/s``: ``F_proc = r·t``. While the roller
   holds (``F_proc ≤ F_max``) it transmits the process force, ``F_f = F_proc``, and the
   filament moves at ``v_fil = v_nom·(1 − s)`` with ``s = k_p + s'·F_f`` [000 Eqs. 1, 6, 8],
   never below 0 (at ``s ≥ 1`` the filament stands although the roller turns).
2. *Failure.* Above ``F_max`` [000 Figs. 4–8] the roller eats into the filament: the
   filament stops and the force collapses to the grinding level
   ``min(F_proc, g·F_max)`` (:class:`~flowtwin.teststand.model.DriveUnderTest`).
3. *Detection.* The stand stops the ramp at the first sample whose **measured** velocity
   is below 0.05 mm/s ("filament blockage measured by encoder").
4. *Release* at 50 N/s to 0 N; the roller grips again once the process force is below the
   grinding level. Then *wait* 5 s.

Measurements add independent Gaussian noise of the :class:`~flowtwin.teststand.model.
Instrument` to the feed force, the pinch force (around its set point) and the velocity;
the optional pinch cross-talk adds one offset per record. Everything random comes from the
``numpy.random.Generator`` passed in, so a seed reproduces a campaign exactly.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.teststand.model import DriveUnderTest, Instrument, Procedure
from flowtwin.teststand.records import Record, RecordKey

__all__ = ["simulate_campaign", "simulate_record"]

FloatArray = npt.NDArray[np.float64]

#: Largest stall force simulated, N (the stand's load cells are rated 200 N [000 §3]).
_MAX_STALL_FORCE_N = 1.0e4


def _loading(drive: DriveUnderTest, fmax: float, gradient: float, speed: float,
             ramp: float, t: FloatArray) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """True feed force, true filament speed and 'failed' flag during the ramp at times t."""
    f_proc = ramp * t
    failed = f_proc > fmax
    force = np.where(failed, np.minimum(f_proc, drive.grind_residual_fraction * fmax), f_proc)
    slip = drive.k_p + gradient * force
    speed_true = np.where(failed, 0.0, speed * np.clip(1.0 - slip, 0.0, None))
    return force, speed_true, failed


def simulate_record(drive: DriveUnderTest, *, pinch_force_n: float, speed_mm_s: float,
                    repeat: int, rng: np.random.Generator,
                    procedure: Procedure | None = None,
                    instrument: Instrument | None = None) -> Record:
    """Simulate one record of the test-stand procedure [000 §3] (module docstring).

    Parameters
    ----------
    drive
        The roller under test.
    pinch_force_n
        Set pinch force ``F_p``, N (> 0).
    speed_mm_s
        Set nominal feed velocity ``v_fil,nom = ω·r``, mm/s (> 0).
    repeat
        Repeat number written to the record.
    rng
        Source of the instrument noise and of the maximum-force scatter.
    procedure
        Ramp, release and wait (default: the paper's).
    instrument
        Sensor noise and sample rate (default: the paper's).

    Returns
    -------
    Record
        Samples from the start of the ramp to the end of the wait.

    Raises
    ------
    ProfileError
        If the pinch force or speed is not positive, or the drive never stalls (no slip and
        no maximum feed force: the procedure would not end).
    """
    proc = procedure or Procedure()
    inst = instrument or Instrument()
    if not (math.isfinite(pinch_force_n) and pinch_force_n > 0.0):
        raise ProfileError("the pinch force must be positive", field="pinch_force_n",
                           value=pinch_force_n, allowed="> 0 N")
    if not (math.isfinite(speed_mm_s) and speed_mm_s > 0.0):
        raise ProfileError("the nominal feed velocity must be positive", field="speed_mm_s",
                           value=speed_mm_s, allowed="> 0 mm/s")
    dt = 1.0 / inst.sample_rate_hz
    gradient = float(drive.slip_gradient_per_n(pinch_force_n, speed_mm_s))
    fmax = float(drive.max_feed_force_n(pinch_force_n))
    if drive.max_force_scatter > 0.0:
        fmax *= 1.0 + drive.max_force_scatter * float(rng.standard_normal())
    fmax = max(fmax, 0.0)
    full_slip_n = (1.0 - drive.k_p) / gradient if gradient > 0.0 else math.inf
    stall_n = min(fmax, full_slip_n)
    if not stall_n <= _MAX_STALL_FORCE_N:
        raise ProfileError("the drive never stalls: neither its maximum feed force nor 100 % "
                           f"slip is reached below {_MAX_STALL_FORCE_N:g} N",
                           field="max_force_coeffs", value=drive.max_force_coeffs,
                           allowed=f"a drive that fails below {_MAX_STALL_FORCE_N:g} N")
    crosstalk = 0.0
    if inst.pinch_crosstalk_fraction > 0.0:
        crosstalk = inst.pinch_crosstalk_fraction * pinch_force_n * float(
            rng.uniform(-1.0, 1.0))

    # Load until the measured speed falls below the stall threshold. The stall happens at
    # stall_n/ramp; look a little beyond and extend if the noise hides it.
    horizon = stall_n / proc.force_ramp_n_s + 2.0
    n_load = 0
    parts_t: list[FloatArray] = []
    parts_f: list[FloatArray] = []
    failed_at_break = False
    v_meas_load: FloatArray = np.empty(0)
    while True:
        n_new = int(math.ceil(horizon / dt)) + 1 - n_load
        t = (n_load + np.arange(n_new, dtype=np.float64)) * dt
        force, speed_true, failed = _loading(drive, fmax, gradient, speed_mm_s,
                                             proc.force_ramp_n_s, t)
        v_meas = speed_true + inst.speed_sigma_mm_s * rng.standard_normal(n_new)
        below = np.flatnonzero(v_meas < proc.stall_speed_mm_s)
        if below.size:
            stop = int(below[0]) + 1
            parts_t.append(t[:stop])
            parts_f.append(force[:stop])
            v_meas_load = np.concatenate([v_meas_load, v_meas[:stop]])
            failed_at_break = bool(failed[stop - 1])
            break
        parts_t.append(t)
        parts_f.append(force)
        v_meas_load = np.concatenate([v_meas_load, v_meas])
        n_load += n_new
        horizon *= 2.0
        if horizon > 4.0 * _MAX_STALL_FORCE_N / proc.force_ramp_n_s:  # guards the loop
            raise ProfileError("the simulated record does not stall", field="speed_mm_s",
                               value=speed_mm_s, allowed="a drive that stalls")
    t_load = np.concatenate(parts_t)
    f_load = np.concatenate(parts_f)

    # Release at 50 N/s from the process force at the break, then wait.
    t_break = float(t_load[-1])
    f_break = proc.force_ramp_n_s * t_break
    t_release_end = t_break + f_break / proc.release_n_s
    t_end = t_release_end + proc.wait_s
    n_rest = int(math.floor((t_end - t_break) / dt + 1e-9))
    t_rest = t_break + dt * np.arange(1, n_rest + 1)
    f_proc = np.clip(f_break - proc.release_n_s * (t_rest - t_break), 0.0, None)
    if failed_at_break:
        grip = f_proc <= drive.grind_residual_fraction * fmax
        # once gripping again the drive transmits the process force
        first_grip = int(np.argmax(grip)) if grip.any() else f_proc.size
        gripping = np.arange(f_proc.size) >= first_grip
    else:
        gripping = np.ones(f_proc.size, dtype=bool)
    f_rest = np.where(gripping, f_proc, np.minimum(f_proc, drive.grind_residual_fraction * fmax))
    s_rest = drive.k_p + gradient * f_rest
    v_rest = np.where(gripping, speed_mm_s * np.clip(1.0 - s_rest, 0.0, None), 0.0)

    t_all = np.concatenate([t_load, t_rest])
    f_all = np.concatenate([f_load, f_rest])
    n_all = t_all.size
    v_meas_rest = v_rest + inst.speed_sigma_mm_s * rng.standard_normal(n_rest)
    feed = f_all + crosstalk + inst.force_sigma_n * rng.standard_normal(n_all)
    pinch = pinch_force_n + inst.force_sigma_n * rng.standard_normal(n_all)
    speed_meas = np.concatenate([v_meas_load, v_meas_rest])
    return Record(key=RecordKey(drive.roller_id, float(pinch_force_n), float(speed_mm_s),
                                int(repeat)),
                  t_s=t_all, filament_speed_mm_s=speed_meas, feed_force_n=feed,
                  pinch_force_n=pinch)


def simulate_campaign(drive: DriveUnderTest, *, seed: int,
                      procedure: Procedure | None = None,
                      instrument: Instrument | None = None) -> tuple[Record, ...]:
    """Run the whole procedure of [000 §3]: every parameter set, every repeat.

    The order is the paper's loop: for each pinch force, for each speed, ``repeats``
    records. One ``numpy.random.default_rng(seed)`` feeds all records in that order.

    Parameters
    ----------
    drive
        The roller under test.
    seed
        Seed of the noise (same seed, same campaign).
    procedure
        Parameter grid and procedure (default: 15 pinch forces × 6 speeds × 3 repeats).
    instrument
        Sensors (default: the paper's).

    Returns
    -------
    tuple of Record
        ``len(pinch_forces) · len(speeds) · repeats`` records.
    """
    proc = procedure or Procedure()
    rng = np.random.default_rng(seed)
    return tuple(
        simulate_record(drive, pinch_force_n=fp, speed_mm_s=v, repeat=r, rng=rng,
                        procedure=proc, instrument=instrument)
        for fp, v in proc.parameter_sets for r in range(proc.repeats)
    )
