"""Per-move physical parameters of the state equation from a machine's profiles.

For every move: nozzle temperature (from ``M104``/``M109``, with the hot end's heater lag)
→ viscosity by the material's law [002] → hydraulic resistance of cone, capillary and the
layer-height dependent back-pressure under the tip [002, 001 Eq. 4] → lag factor
``K = k·R_hyd·A²`` (docs/spec.md §3.4) with the column compliance ``k`` [002, 001 Eq. 2]; the slip
law of the drive's roller at its pinch force [000 Eqs. 6, 8] and its maximum feed force
[000 Figs. 4–8].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.dynamics import ExtrusionParams, move_temperatures
from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.physics.compliance import bowden_compliance_mm_per_n, compliance_mm_per_n
from flowtwin.physics.lag import lag_factor_s
from flowtwin.physics.melt_history import MeltState
from flowtwin.physics.nozzle import hydraulic_resistance_mpa_s_per_mm3
from flowtwin.physics.units import pa_s_to_mpa_s
from flowtwin.planner.timeline import Timeline
from flowtwin.profiles.machine import Machine
from flowtwin.simulation.viscosity import viscosity_pa_s

__all__ = ["THIN_LAYER_FRACTION", "MoveParameters", "OperatingPoint", "layer_heights_mm",
           "move_parameters", "operating_point", "thin_layer_moves", "viscosity_pa_s"]

#: The most filament one move may feed or pull back, mm (100 m: a 1 kg spool of 1.75 mm
#: PLA holds about 330 m; no print feeds a third of a spool in one move). Beyond it the
#: twin refuses the file instead of integrating years of extrusion.
MAX_MOVE_FILAMENT_MM = 1.0e5

#: Eq. 8 of [000] holds for pinch forces of 80–130 N only [000 §4.2].
_EQ8_PINCH_RANGE_N = (80.0, 130.0)


@dataclass(frozen=True, slots=True)
class MoveParameters:
    """Everything the integrator and the deposition model need, per move.

    Attributes
    ----------
    params
        The state-equation parameters (lag, compliance, slip, max force).
    temperature_c
        Nozzle temperature during each move, °C, shape ``(n,)``.
    layer_height_mm
        Layer height of each move, mm, shape ``(n,)``.
    viscosity_pa_s
        Melt viscosity during each move, Pa·s, shape ``(n,)``.
    slip_law
        ``"eq6"`` or ``"eq8"``: which law of [000] gives the slip gradient.
    warnings
        Extrapolations and substitutions, each said once (never silent).
    melt_temperature_c
        Mean melt temperature at the nozzle during each move (melt model,
        :mod:`flowtwin.physics.melt`), °C, shape ``(n,)``; ``None`` without melt model
        (the melt is at ``temperature_c``).
    flow_mm3_s
        Mean flow of fresh filament of each move (``A·fresh·M221/duration``,
        :func:`fresh_filament_mm`; 0 for travels, retractions and unretractions), mm³/s,
        shape ``(n,)``.
    melt_end_c
        Melt temperature after the last move and its rest, °C.
    melt_state
        The melt zone's memory after the last move (carried to the next stretch of a
        streamed file, :class:`~flowtwin.physics.melt_history.MeltState`).
    flow_limit_mm3_s
        The machine's maximum volumetric flow at each move's nozzle temperature
        (:func:`flowtwin.simulation.limits.flow_flags`), mm³/s, shape ``(n,)``.
    over_flow_limit
        Extruding moves that ask for more than that, shape ``(n,)``.
    """

    params: ExtrusionParams
    temperature_c: npt.NDArray[np.float64]
    layer_height_mm: npt.NDArray[np.float64]
    viscosity_pa_s: npt.NDArray[np.float64]
    slip_law: str
    warnings: tuple[str, ...] = field(default_factory=tuple)
    melt_temperature_c: npt.NDArray[np.float64] | None = None
    flow_mm3_s: npt.NDArray[np.float64] | None = None
    melt_end_c: float | None = None
    melt_state: MeltState | None = None
    flow_limit_mm3_s: npt.NDArray[np.float64] | None = None
    over_flow_limit: npt.NDArray[np.bool_] | None = None


#: A layer that rises less than this fraction of the nominal layer height over the layer
#: below is a step of a spiral, not a layer.
THIN_LAYER_FRACTION = 0.25


def layer_heights_mm(table: MoveTable, *, default_mm: float, max_mm: float
                     ) -> npt.NDArray[np.float64]:
    """Layer height of every move, mm: the rise of its layer over the layer below.

    Layers whose Z is unknown take the highest Z of their printing moves (extruding, with XY
    motion: the layer's top, as slicers mark it; in a spiral layer the first extrusion lies
    only a step above the layer below); moves before the first layer, and heights outside
    ``(0, max_mm]``, take ``default_mm``; so do layers thinner than
    :data:`THIN_LAYER_FRACTION` of it (see :func:`thin_layer_moves`). A layer lower than the
    one before and at most ``max_mm`` above the bed lies on the bed (the next object of a
    sequential print): its height is its Z.
    """
    return _layer_heights(table, default_mm=default_mm, max_mm=max_mm)[0]


def thin_layer_moves(table: MoveTable, *, default_mm: float, max_mm: float) -> int:
    """Extruding moves whose layer was too thin to be one (given ``default_mm``).

    A file without layer markers gets a layer per rise of Z (:mod:`flowtwin.gcode`), so a
    spiral vase without markers has one "layer" per rising move, a few µm above the one
    before. The melt under the nozzle is then the turn below, about one nominal layer
    height lower, not the step before: :func:`layer_heights_mm` gives such moves
    ``default_mm`` (a 4 µm gap would put an absurd back-pressure [002] on them).
    """
    return _layer_heights(table, default_mm=default_mm, max_mm=max_mm)[1]


def _layer_heights(table: MoveTable, *, default_mm: float, max_mm: float
                   ) -> tuple[npt.NDArray[np.float64], int]:
    m = table.moves
    n = len(m)
    layer = m["layer"]
    kind = m["kind"]
    extrude = int(MoveKind.EXTRUDE)
    n_layers = int(layer.max()) + 1 if n else 0
    z = np.full(n_layers, np.nan)
    z[: min(n_layers, len(table.layer_z))] = table.layer_z[:n_layers]
    missing = np.flatnonzero(np.isnan(z))
    if missing.size:
        # printing moves only: a slicer may un-retract (E only) at the next layer's Z
        # before that layer's marker (CuraEngine's Griffin and UltiGCode flavors)
        z_top = _layer_top_z(layer, m["z"], kind, extrude | int(MoveKind.XY), n_layers)
        z_top[np.isneginf(z_top)] = np.nan
        z[missing] = z_top[missing]
    h_layer = np.diff(np.concatenate(([0.0], z)))
    # a layer below the one before, within a layer of the bed: the first layer of the next
    # object of a sequential print (or of a second print in the file), on the bed
    with np.errstate(invalid="ignore"):
        on_bed = (h_layer <= 0.0) & (z > 0.0) & (z <= max_mm)
    h_layer = np.where(on_bed, z, h_layer)
    # NaN (no Z at all) is not thin: it takes the default below anyway, unreported
    thin = h_layer < THIN_LAYER_FRACTION * default_mm
    ok = np.isfinite(h_layer) & (h_layer > 0.0) & (h_layer <= max_mm) & ~thin
    h_layer = np.where(ok, h_layer, default_mm)
    out = np.empty(n)  # (numpy's pages: huge pages on large arrays)
    n_thin = _spread_heights(layer, kind, extrude, h_layer, thin, float(default_mm), out)
    return out, n_thin


@njit(cache=True, nogil=True)
def _layer_top_z(layer: npt.NDArray[np.int32], z: npt.NDArray[np.float64],
                 kind: npt.NDArray[np.uint8], bits: int, n_layers: int
                 ) -> npt.NDArray[np.float64]:
    """Highest Z of each layer's moves whose kind has all of ``bits`` (``-inf``: none; NaN
    if any is NaN, as ``np.maximum``), one pass over the record fields in place."""
    top = np.full(n_layers, -np.inf)
    for k in range(layer.shape[0]):
        lay = layer[k]
        if lay >= 0 and (kind[k] & bits) == bits:
            v = float(z[k])
            if v != v or v > top[lay]:  # (a NaN top stays NaN: v > NaN is False)
                top[lay] = v
    return top


@njit(cache=True, nogil=True)
def _spread_heights(layer: npt.NDArray[np.int32], kind: npt.NDArray[np.uint8], extrude: int,
                    h_layer: npt.NDArray[np.float64], thin: npt.NDArray[np.bool_],
                    default_mm: float, out: npt.NDArray[np.float64]) -> int:
    """``out[k]``: the height of move ``k``'s layer (``default_mm`` before the first
    layer); returns the number of extruding moves in thin layers."""
    n_thin = 0
    for k in range(layer.shape[0]):
        lay = layer[k]
        if lay >= 0:
            out[k] = h_layer[lay]
            if thin[lay] and (kind[k] & extrude) != 0:
                n_thin += 1
        else:
            out[k] = default_mm
    return n_thin


def _run_starts(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]
                ) -> npt.NDArray[np.int64]:
    """First index of every run of equal ``(a, b)`` pairs (NaN starts a run of its own)."""
    if a.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    change = np.flatnonzero((a[1:] != a[:-1]) | (b[1:] != b[:-1])) + 1
    return np.concatenate((np.zeros(1, dtype=np.int64), change)).astype(np.int64)


def _check_filament_per_move(table: MoveTable) -> None:
    """Refuse a move that feeds or pulls back more than :data:`MAX_MOVE_FILAMENT_MM`: its E
    times the ``M221`` flow in force (``M221 S999999999`` makes an ``E15`` purge feed
    150 km, which the twin would otherwise grind through for minutes)."""
    de = np.abs(np.asarray(table.moves["de"], dtype=np.float64)
                * np.asarray(table.moves["flow"], dtype=np.float64))
    big = np.flatnonzero(~(de <= MAX_MOVE_FILAMENT_MM))
    if big.size:
        i = int(big[0])
        flow = float(table.moves["flow"][i])
        by = ("" if flow == 1.0
              else f" (E {float(table.moves['de'][i]):.6g} at M221 {100 * flow:g} %)")
        raise DataError(f"a move feeds {float(de[i]):.6g} mm of filament{by}; "
                        f"{big.size} move(s) beyond the limit", source=table.source,
                        line=int(table.moves["line"][i]), field="E", value=float(de[i]),
                        allowed=f"at most {MAX_MOVE_FILAMENT_MM:g} mm per move (100 m)")


def move_parameters(machine: Machine, table: MoveTable, timeline: Timeline, *,
                    temperature_c: float | None = None, melt_start: MeltState | None = None,
                    flag_flow_limit: bool = True) -> MoveParameters:
    """Per-move parameters of the extrusion state equation for ``machine``.

    Parameters
    ----------
    machine
        The resolved set-up (printer, drive, hot end, material, filament).
    table, timeline
        The read and planned G-code.
    temperature_c
        Nozzle temperature before the G-code sets one, °C (default: the set-up's).
    melt_start
        The melt zone's memory before the first move (melt model; default: fully heated).
    flag_flow_limit
        Flag the moves above the machine's maximum volumetric flow
        (:func:`flowtwin.simulation.limits.flow_flags`).

    Returns
    -------
    MoveParameters
    """
    n = len(table)
    _check_filament_per_move(table)
    warnings: list[str] = []
    hot = machine.hotend
    mat = machine.material
    area = machine.filament.area_mm2
    initial = machine.temperature_c if temperature_c is None else temperature_c
    temps = move_temperatures(table, timeline, initial_c=initial,
                              heater_tau_s=hot.heater_time_constant_s or 0.0)
    lo, hi = mat.viscosity.t_min_c, mat.viscosity.t_max_c
    outside = (temps < lo) | (temps > hi)
    extruding = (table.moves["kind"] & MoveKind.EXTRUDE) != 0
    flow, melt_c, melt_state = _melt_temperatures(machine, table, timeline, temps, melt_start)
    if np.any(outside & extruding):
        k = int(np.flatnonzero(outside & extruding)[0])
        warnings.append(
            f"{int(np.count_nonzero(outside & extruding))} extruding moves at a nozzle "
            f"temperature outside the viscosity law's range {lo:g}–{hi:g} °C (first: line "
            f"{int(table.moves['line'][k])}, {temps[k]:.1f} °C); the law is evaluated at the "
            "nearest end of its range there (extrapolation refused)")
    t_melt = temps if melt_c is None else melt_c
    cold = (t_melt < lo) & ~outside & extruding
    if np.any(cold):
        k = int(np.flatnonzero(cold)[0])
        warnings.append(
            f"{int(np.count_nonzero(cold))} extruding moves ask for more than the hot end can "
            f"melt: the melt reaches the nozzle below the viscosity law's range (first: line "
            f"{int(table.moves['line'][k])}, {t_melt[k]:.1f} °C at {flow[k]:.1f} mm³/s); the "
            f"law is evaluated at {lo:g} °C there, so their feed force is a lower bound")
    t_eval = np.clip(t_melt, lo, hi)
    default_h = machine.setup.layer_height_mm or float(
        table.metadata.get("layer_height_mm", 0.2) or 0.2)  # type: ignore[arg-type]
    h, n_thin = _layer_heights(table, default_mm=default_h, max_mm=hot.nozzle_diameter_mm)
    if n_thin:
        warnings.append(f"{n_thin} extruding moves lie in layers less than "
                        f"{THIN_LAYER_FRACTION * default_h:.3g} mm above the layer below (a "
                        "spiral without layer markers?): they are given the nominal layer "
                        f"height {default_h:g} mm, the gap to the turn below")
    # the physics once per run of moves at the same temperature and layer height (most
    # moves share them with the move before): the same numbers, element by element
    run = _run_starts(t_eval, h)
    counts = np.diff(np.append(run, n))
    visc_run = viscosity_pa_s(mat, t_eval[run])
    visc_pa_s = np.repeat(visc_run, counts)
    resistance = hydraulic_resistance_mpa_s_per_mm3(
        pa_s_to_mpa_s(visc_run), capillary_length_mm=hot.land_length_mm,
        nozzle_radius_mm=hot.nozzle_diameter_mm / 2.0,
        bore_radius_mm=hot.bore_diameter_mm / 2.0, cone_half_angle_deg=hot.cone_half_angle_deg,
        layer_height_mm=h[run], back_pressure_length_mm=hot.back_pressure_length_mm,
        back_pressure_exponent=hot.back_pressure_exponent)
    k_col = float(compliance_mm_per_n(area, hot.l_rt_mm, mat.e_rt_mpa, hot.l_hot_mm,
                                      mat.e_hot_mpa))
    if hot.bowden is not None:
        tube = hot.bowden
        k_col += float(bowden_compliance_mm_per_n(
            tube.length_mm, tube.outer_diameter_mm, tube.inner_diameter_mm, tube.modulus_mpa,
            machine.filament.diameter_mm, mat.e_rt_mpa))
    lag = np.repeat(lag_factor_s(k_col, resistance, area), counts)

    roller = machine.roller
    fp = machine.drive.pinch_force_n
    use_eq8 = (roller.velocity_dependent
               and _EQ8_PINCH_RANGE_N[0] <= fp <= _EQ8_PINCH_RANGE_N[1])
    if use_eq8:
        grad = float(roller.a_per_n)  # type: ignore[arg-type]
        gain = float(roller.b_per_n)  # type: ignore[arg-type]
        decay = float(roller.c_s_per_mm)  # type: ignore[arg-type]
    else:
        grad = roller.k_s_n / fp ** 2 + roller.k_inf_per_n
        gain, decay = 0.0, 0.0
        if roller.velocity_dependent:
            warnings.append(f"pinch force {fp:g} N is outside 80–130 N where the velocity "
                            "law [000 Eq. 8] holds; using Eq. 6 without velocity dependence")
    fit = roller.max_feed_force_fit
    max_force = fit.max_feed_force_n(fp) if fit is not None else math.inf
    if fit is None:
        warnings.append(f"roller {roller.name} has no maximum feed force fit: grinding is "
                        "not predicted")
    params = ExtrusionParams.build(
        n, lag_k_s=lag,
        compliance_mm_per_n=k_col, filament_diameter_mm=machine.filament.diameter_mm,
        slip_offset=machine.drive.k_p, slip_gradient_per_n=grad,
        slip_velocity_gain_per_n=gain, slip_velocity_decay_s_per_mm=decay,
        max_feed_force_n=max_force)
    limit = over = None
    if flag_flow_limit:
        from flowtwin.simulation.limits import flow_flags

        flags = flow_flags(machine, flow, temps,
                           extruding & ((table.moves["kind"] & MoveKind.XY) != 0), h)
        limit, over = flags.limit_mm3_s, flags.over
        if flags.count:
            k = int(np.flatnonzero(over)[0])
            warnings.append(
                f"{flags.count} extruding moves ask for more than the machine's maximum "
                f"volumetric flow (first: line {int(table.moves['line'][k])}, "
                f"{flow[k]:.1f} > {limit[k]:.1f} mm³/s at {temps[k]:.0f} °C and "
                f"{h[k]:.2f} mm layers; flowtwin limits tells why)")
    return MoveParameters(params=params, temperature_c=temps, layer_height_mm=h,
                          viscosity_pa_s=visc_pa_s, slip_law="eq8" if use_eq8 else "eq6",
                          warnings=tuple(warnings), melt_temperature_c=melt_c,
                          flow_mm3_s=flow, melt_state=melt_state,
                          melt_end_c=None if melt_state is None else melt_state.end_c,
                          flow_limit_mm3_s=limit,
                          over_flow_limit=over)


def fresh_filament_mm(de_mm: npt.NDArray[np.float64], tool: npt.NDArray[np.integer], *,
                      retracted_mm: tuple[tuple[int, float], ...] = ()
                      ) -> tuple[npt.NDArray[np.float64], tuple[tuple[int, float], ...]]:
    """Filament each move feeds into its hot end for the first time, mm, shape ``(n,)``.

    A retraction draws filament back out of the melt zone and the unretraction after it
    pushes the same, already heated filament in again: only filament beyond the furthest
    point fed so far (per tool) is cold material that the melt zone must heat. So a move
    feeds ``max(0, C_k − max(0, H_{k−1}))`` where ``C`` is the tool's cumulative feed and
    ``H`` its running maximum.

    Parameters
    ----------
    de_mm
        Filament fed by every move (after the flow factor; negative: retraction), mm.
    tool
        Tool of every move (each tool has its own hot end and filament).
    retracted_mm
        ``(tool, mm)`` below the furthest feed before the first move (a stream's carry).

    Returns
    -------
    (fresh, retracted)
        Fresh filament per move, mm, and the ``(tool, mm)`` below the furthest feed after
        the last move.
    """
    out = np.zeros(de_mm.shape[0])
    below = dict(retracted_mm)
    one = tool.size > 0 and tool.min() == tool.max()  # one tool: every row, no gather
    for t in (tool[:1] if one else np.unique(tool)):
        rows = slice(None) if one else np.flatnonzero(tool == t)
        c = np.cumsum(de_mm[rows]) - below.get(int(t), 0.0)
        high = np.maximum(np.maximum.accumulate(c), 0.0)
        before = np.concatenate(([0.0], high[:-1]))
        out[rows] = np.maximum(c - before, 0.0)
        below[int(t)] = float(high[-1] - c[-1])
    return out, tuple(sorted(below.items()))


def _melt_temperatures(machine: Machine, table: MoveTable, timeline: Timeline,
                       temps: npt.NDArray[np.float64], start: MeltState | None
                       ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None,
                                  MeltState | None]:
    """Mean flow of fresh filament into the melt zone of every move and, with a melt model,
    the melt temperature from the plug's residence history
    (:func:`flowtwin.physics.melt_history.melt_temperature_history`)."""
    from flowtwin.physics.melt_history import melt_temperature_history
    from flowtwin.simulation.limits import melt_model

    ph = timeline.phases
    start_s = np.asarray(ph["t_start"], dtype=np.float64)
    dur = np.asarray(ph["accel_t"] + ph["cruise_t"] + ph["decel_t"], dtype=np.float64)
    m = table.moves
    area = machine.filament.area_mm2
    carried = start.retracted_mm if start is not None else ()
    fresh, below = fresh_filament_mm(m["de"] * m["flow"].astype(np.float64), m["tool"],
                                     retracted_mm=carried)
    feeding = (fresh > 0.0) & (dur > 0.0)
    flow = np.zeros(len(m))
    np.divide(area * fresh, dur, out=flow, where=feeding)
    model = melt_model(machine)
    if model is None or len(m) == 0:
        return flow, None, None
    end_s = max(float(timeline.total_time_s), float(start_s[-1] + dur[-1]))
    mean, state = melt_temperature_history(
        flow, start_s, dur, temps, inlet_c=model.inlet_c,
        diffusivity_mm2_s=model.diffusivity_mm2_s, heated_length_mm=model.heated_length_mm,
        filament_radius_mm=machine.filament.diameter_mm / 2.0, state=start, end_s=end_s,
        retracted_mm=below)
    return flow, mean, state


@dataclass(frozen=True, slots=True)
class OperatingPoint:
    """Steady extrusion of one machine at one feed (docs/spec.md §3.3–3.4).

    Attributes
    ----------
    lag_k_s
        Lag factor ``K = k·R_hyd·A²``, s.
    compliance_mm_per_n
        Column compliance ``k``, mm/N.
    resistance_mpa_s_per_mm3
        Hydraulic resistance of the hot end, MPa·s/mm³.
    nominal_force_n
        Feed force the nominal feed would need, ``F_0 = R_hyd·Q·A``, N.
    slip
        Steady slip ``(k_p + s'F_0)/(1 + s'F_0)`` [000 Eq. 6 with F ∝ flow], fraction.
    max_feed_force_n
        The roller's maximum feed force at the drive's pinch force, N.
    """

    lag_k_s: float
    compliance_mm_per_n: float
    resistance_mpa_s_per_mm3: float
    nominal_force_n: float
    slip: float
    max_feed_force_n: float


def operating_point(machine: Machine, *, feed_mm_s: float, temperature_c: float | None = None,
                    layer_height_mm: float | None = None) -> OperatingPoint:
    """The machine extruding steadily at ``feed_mm_s`` of filament.

    ``layer_height_mm=None`` is free extrusion into air (no back-pressure under the tip),
    as in the slip measurements of [003].
    """
    from flowtwin.physics.drive import slip_gradient_velocity, steady_state_slip

    hot = machine.hotend
    mat = machine.material
    area = machine.filament.area_mm2
    temp = machine.temperature_c if temperature_c is None else temperature_c
    visc = float(viscosity_pa_s(mat, temp))
    r_hyd = float(hydraulic_resistance_mpa_s_per_mm3(
        pa_s_to_mpa_s(visc), capillary_length_mm=hot.land_length_mm,
        nozzle_radius_mm=hot.nozzle_diameter_mm / 2.0,
        bore_radius_mm=hot.bore_diameter_mm / 2.0, cone_half_angle_deg=hot.cone_half_angle_deg,
        layer_height_mm=layer_height_mm, back_pressure_length_mm=hot.back_pressure_length_mm,
        back_pressure_exponent=hot.back_pressure_exponent))
    k_col = float(compliance_mm_per_n(area, hot.l_rt_mm, mat.e_rt_mpa, hot.l_hot_mm,
                                      mat.e_hot_mpa))
    force0 = r_hyd * feed_mm_s * area * area
    roller = machine.roller
    fp = machine.drive.pinch_force_n
    if roller.velocity_dependent and _EQ8_PINCH_RANGE_N[0] <= fp <= _EQ8_PINCH_RANGE_N[1]:
        grad = float(slip_gradient_velocity(
            feed_mm_s, float(roller.a_per_n),  # type: ignore[arg-type]
            float(roller.b_per_n), float(roller.c_s_per_mm)))  # type: ignore[arg-type]
    else:
        grad = roller.k_s_n / fp ** 2 + roller.k_inf_per_n
    fit = roller.max_feed_force_fit
    return OperatingPoint(
        lag_k_s=float(lag_factor_s(k_col, r_hyd, area)), compliance_mm_per_n=k_col,
        resistance_mpa_s_per_mm3=r_hyd, nominal_force_n=force0,
        slip=float(steady_state_slip(force0, grad, k_p=machine.drive.k_p)),
        max_feed_force_n=fit.max_feed_force_n(fp) if fit is not None else math.inf)
