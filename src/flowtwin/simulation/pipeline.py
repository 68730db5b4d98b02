"""``simulate``: read, plan, derive the physics, integrate, deposit."""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import BinaryIO

from flowtwin.defaults import DEFAULT_MACHINE
from flowtwin.dynamics import AdvanceSettings, predict, printer_advance
from flowtwin.errors import GcodeError
from flowtwin.firmware import Firmware
from flowtwin.planner.plan_file import PlanResult, plan_gcode
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.simulation.parameters import move_parameters
from flowtwin.simulation.result import SimulationResult, deposition_metrics

__all__ = ["DEFAULT_MACHINE", "simulate", "simulate_plan"]


Progress = Callable[[str], None]


def simulate(source: str | os.PathLike[str] | bytes | BinaryIO, *,
             machine: Machine | SetupProfile | str | os.PathLike[str] | None = None,
             klipper_config: str | os.PathLike[str] | None = None,
             pressure_advance: bool = True, series_dt_s: float | None = None,
             temperature_c: float | None = None, use_slicer_limits: bool = False,
             progress: Progress | None = None) -> SimulationResult:
    """Predict what ``source`` extrudes on ``machine``.

    Parameters
    ----------
    source
        G-code path (plain or gzip), ``"-"`` for stdin, bytes or a binary stream.
    machine
        The set-up: a :class:`Machine`, a set-up profile, a built-in set-up name or a
        set-up TOML file; default :data:`DEFAULT_MACHINE`.
    klipper_config
        Plan with this Klipper ``printer.cfg`` instead of the set-up's printer (the drive,
        hot end and material still come from the set-up; pressure advance from the cfg).
    pressure_advance
        Include the firmware's pressure advance (profile value and the G-code's ``M900`` /
        ``M572`` / ``SET_PRESSURE_ADVANCE``); ``False`` predicts the bare G-code.
    series_dt_s
        Also return a time series sampled every ``series_dt_s`` seconds (decimated).
    temperature_c
        Nozzle temperature before the G-code sets one (default: the set-up's).
    use_slicer_limits
        Marlin-style firmware: plan with the slicer's embedded machine limits.
    progress
        Called with the name of each stage as it starts.

    Returns
    -------
    SimulationResult

    Raises
    ------
    GcodeError, ProfileError
        Bad G-code or profiles; a file without moves.
    """
    step = progress or (lambda _stage: None)
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    step("read and plan")
    plan = plan_gcode(source, printer=m.printer, klipper_config=klipper_config,
                      use_slicer_limits=use_slicer_limits)
    if len(plan.table) == 0:
        raise GcodeError("no moves to simulate", source=plan.table.source,
                         allowed="G-code with at least one G0/G1/G2/G3 move")
    return simulate_plan(plan, machine=m, klipper_config=klipper_config,
                         pressure_advance=pressure_advance, series_dt_s=series_dt_s,
                         temperature_c=temperature_c, progress=progress)


def simulate_plan(plan: PlanResult, *, machine: Machine,
                  klipper_config: str | os.PathLike[str] | None = None,
                  pressure_advance: bool = True, series_dt_s: float | None = None,
                  temperature_c: float | None = None,
                  progress: Progress | None = None) -> SimulationResult:
    """Predict what a read and planned G-code extrudes on ``machine``.

    The part of :func:`simulate` after reading and planning: for a move table made in
    memory (compensation's drafts) and planned with :func:`flowtwin.planner.plan_file.plan_table`.

    Parameters
    ----------
    plan
        The table and its plan (non-empty).
    machine
        The set-up.
    klipper_config
        The Klipper ``printer.cfg`` the plan was made with, if any (the firmware's
        pressure advance is then the cfg's).
    pressure_advance, series_dt_s, temperature_c, progress
        As for :func:`simulate`.

    Returns
    -------
    SimulationResult
    """
    step = progress or (lambda _stage: None)
    m = machine
    step("physics")
    params = move_parameters(m, plan.table, plan.timeline, temperature_c=temperature_c)
    advance = None
    label = "off"
    if pressure_advance:
        if klipper_config is not None:
            ex = plan.settings.extruders[0]  # type: ignore[union-attr]
            advance = AdvanceSettings(Firmware.KLIPPER, k_s=ex.pressure_advance,
                                      smooth_time_s=ex.pressure_advance_smooth_time)
        else:
            advance = printer_advance(m.printer)
        label = f"{advance.firmware.value} K={advance.k_s:g} s (+ G-code commands)"
    step("integrate")
    dyn = predict(plan.table, plan.timeline, params.params, advance=advance,
                  series_dt_s=series_dt_s)
    step("deposit")
    metrics = deposition_metrics(plan, dyn, params)
    warnings = [*params.warnings, *dyn.warnings]
    return SimulationResult(plan=plan, machine_name=m.name, parameters=params, dynamics=dyn,
                            metrics=metrics, advance=label, warnings=warnings,
                            nozzle_diameter_mm=float(m.hotend.nozzle_diameter_mm))
