"""Which printer and set-up a post-processed file is planned and simulated for.

Motion (the planner and its limits), in order:

1. a Klipper ``printer.cfg`` (``--klipper-config``, or the live configuration a Klipper
   printer's Moonraker reports, :mod:`flowtwin.postprocess.moonraker`) — the firmware's own
   settings, nothing of the slicer's limits;
2. else the slicer's settings (``SLIC3R_*`` environment, else the block embedded in the
   G-code): ``gcode_flavor`` picks the firmware, the ``machine_max_*`` limits replace the
   printer profile's (the set-up's printer when it is of the same planner family, else
   flowtwin's generic one of that family);
3. else the set-up's printer profile alone.

Physics (drive, hot end, material, filament) always come from the set-up (``--profile``),
with the slicer's nozzle diameter, filament diameter and temperature when it gives them.
Everything this module changes is listed in :attr:`PrinterChoice.notes`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from flowtwin.errors import ProfileError
from flowtwin.firmware import Firmware, PlannerFamily
from flowtwin.planner.from_profile import marlin_settings
from flowtwin.planner.marlin import MarlinSettings, marlin_settings_from_slicer_config
from flowtwin.postprocess.slicer import SlicerSettings, first_float
from flowtwin.profiles.machine import Machine, check_machine, load_machine
from flowtwin.profiles.printer import PrinterProfile

__all__ = ["PrinterChoice", "firmware_of_flavor", "resolve_printer"]

#: ``gcode_flavor`` values flowtwin plans as that firmware.
_FLAVORS: dict[str, Firmware] = {
    "klipper": Firmware.KLIPPER,
    "marlin": Firmware.MARLIN,
    "marlin2": Firmware.MARLIN,
    "marlinlegacy": Firmware.MARLIN,
    "marlinfirmware": Firmware.MARLIN,
    "reprapfirmware": Firmware.REPRAPFIRMWARE,
    "repetier": Firmware.REPETIER,
}
#: ``printer_model`` prefixes of Prusa printers running the 32-bit Buddy firmware (``M572``
#: advance); the MK3S and MK2.5 run the 8-bit, Marlin-based Prusa-Firmware.
_BUDDY_MODELS = ("MK4", "MK3.9", "MK3.5", "XL", "MINI", "COREONE", "CORE ONE")
#: A slicer filament diameter this far from the set-up's measured one is another filament
#: size (the firmware and the E values always use the slicer's nominal diameter), mm.
_OTHER_FILAMENT_MM = 0.1


@dataclass(frozen=True, slots=True)
class PrinterChoice:
    """The printer and set-up of a post-processing run.

    Attributes
    ----------
    machine
        The set-up with the printer profile used (when ``klipper_config`` is set, its
        printer only supplies what a ``printer.cfg`` does not: the physics ignore it).
    klipper_config
        The Klipper ``printer.cfg`` that plans the moves, or ``None``.
    source
        ``"klipper-config"``, ``"moonraker"``, ``"slicer settings (environment)"``,
        ``"slicer settings (embedded)"`` or ``"profile"``.
    label
        One line naming the printer configuration.
    firmware
        The firmware the file is planned for.
    notes
        What was taken from where, and what could not be modelled.
    silent
        Printer profile with the slicer's second (silent / stealth mode) machine limits,
        for the silent-mode figures PrusaSlicer writes; ``None`` when there are none.
    """

    machine: Machine
    klipper_config: Path | None
    source: str
    label: str
    firmware: Firmware
    notes: tuple[str, ...] = ()
    silent: PrinterProfile | None = None


def firmware_of_flavor(flavor: str | None, printer_model: str | None
                       ) -> tuple[Firmware | None, str | None]:
    """The firmware a slicer's ``gcode_flavor`` stands for, and a note when flowtwin has no
    model of it (then planned as Marlin). ``(None, None)`` without a flavor."""
    if not flavor:
        return None, None
    fw = _FLAVORS.get(flavor)
    if fw is Firmware.MARLIN and printer_model and \
            printer_model.upper().replace(" ", "").startswith(_BUDDY_MODELS):
        return Firmware.PRUSA, None
    if fw is None:
        return Firmware.MARLIN, (f"the slicer's G-code flavor {flavor!r} is not modelled by "
                                 "flowtwin: planned with the Marlin planner")
    return fw, None


def _marlin_limits(ms: MarlinSettings, base: PrinterProfile) -> dict[str, object]:
    """A ``[marlin]`` profile table for Marlin settings ``ms`` (base: what they lack)."""
    assert base.marlin is not None
    keys = ("x", "y", "z", "e")
    table = base.marlin.model_dump()
    table.update({
        "max_feedrate_mm_s": dict(zip(keys, ms.max_feedrate_mm_s, strict=True)),
        "max_acceleration_mm_s2": dict(zip(keys, ms.max_acceleration_mm_s2, strict=True)),
        "print_accel_mm_s2": ms.print_accel_mm_s2,
        "retract_accel_mm_s2": ms.retract_accel_mm_s2,
        "travel_accel_mm_s2": ms.travel_accel_mm_s2,
        "min_feedrate_mm_s": ms.min_feedrate_mm_s,
        "min_travel_feedrate_mm_s": ms.min_travel_feedrate_mm_s,
    })
    if ms.junction_deviation_mm is None:
        table["jerk_mm_s"] = dict(zip(keys, ms.jerk_mm_s, strict=True))
        table["junction_deviation_mm"] = None
        table["e_jerk_mm_s"] = None
    else:
        table["junction_deviation_mm"] = ms.junction_deviation_mm
        table["jerk_mm_s"] = None
        table["e_jerk_mm_s"] = ms.jerk_mm_s[3]
    return table


def _validated(data: dict[str, object], what: str) -> PrinterProfile:
    try:
        return PrinterProfile.model_validate(data)
    except ValueError as exc:  # pydantic's ValidationError
        raise ProfileError(f"the slicer's settings give an invalid printer: {exc}",
                           field=what) from exc


def _slicer_printer(base: PrinterProfile, settings: SlicerSettings, fw: Firmware,
                    options: dict[str, str], notes: list[str]) -> PrinterProfile:
    """``base`` (of ``fw``'s planner family) with the slicer's limits and diameters."""
    data = base.model_dump()
    data["firmware"] = fw.value
    data["name"] = f"{base.name}+slicer-limits"
    if fw.planner is PlannerFamily.KLIPPER:
        lim = dict(data["limits"])  # type: ignore[call-overload]
        vx = first_float(settings.get("machine_max_feedrate_x", "machine_max_speed_x"))
        vy = first_float(settings.get("machine_max_feedrate_y", "machine_max_speed_y"))
        ax = first_float(settings.get("machine_max_acceleration_x"))
        ay = first_float(settings.get("machine_max_acceleration_y"))
        speeds = [v for v in (vx, vy) if v]
        accels = [a for a in (ax, ay) if a]
        if speeds:
            lim["max_velocity_mm_s"] = min(speeds)
        if accels:
            lim["max_accel_mm_s2"] = min(accels)
        for key in ("max_z_velocity_mm_s", "max_z_accel_mm_s2"):
            cap = lim["max_velocity_mm_s" if "velocity" in key else "max_accel_mm_s2"]
            if lim.get(key) is not None and lim[key] > cap:
                lim[key] = cap
        data["limits"] = lim
        if speeds or accels:
            notes.append("Klipper's max_velocity and max_accel from the slicer's X/Y machine "
                         "limits, the rest from the printer profile: give --klipper-config "
                         "or --moonraker for the printer's own printer.cfg")
    else:
        sl = marlin_settings_from_slicer_config(options, base=marlin_settings(base))
        if sl is None:
            notes.append("the slicer gives no machine limits (or ignores them): the "
                         "printer profile's limits are used")
        else:
            data["marlin"] = _marlin_limits(sl, base)
    return _validated(data, "machine_max_*")


def _base_printer(machine: Machine, fw: Firmware) -> PrinterProfile:
    from flowtwin.profiles import load_builtin

    if machine.printer.firmware.planner is fw.planner:
        return machine.printer
    loaded = load_builtin(fw.default_printer, "printer")
    assert isinstance(loaded, PrinterProfile)
    return loaded


def _with_physics(machine: Machine, printer: PrinterProfile, settings: SlicerSettings | None,
                  notes: list[str]) -> Machine:
    """The machine with ``printer`` and the slicer's nozzle, filament and temperature."""
    hotend, filament, setup = machine.hotend, machine.filament, machine.setup
    pdata = printer.model_dump()
    if settings is not None:
        d = settings.nozzle_diameter_mm
        if d is not None and abs(d - hotend.nozzle_diameter_mm) > 1e-9:
            notes.append(f"the slicer's {d:g} mm nozzle replaces the {hotend.nozzle_diameter_mm:g}"
                         f" mm of hot end {hotend.name!r} (its other dimensions are kept)")
            hotend = hotend.model_copy(update={"nozzle_diameter_mm": d})
        f = settings.filament_diameter_mm
        if f is not None and abs(f - filament.diameter_mm) > _OTHER_FILAMENT_MM:
            # another filament size (2.85 against 1.75 mm), not the set-up's measured one
            notes.append(f"the slicer's {f:g} mm filament replaces the {filament.diameter_mm:g}"
                         f" mm of filament {filament.name!r}")
            filament = filament.model_copy(update={"diameter_mm": f})
        t = settings.temperature_c
        if t is not None and abs(t - setup.temperature_c) > 1e-9:
            setup = setup.model_copy(update={"temperature_c": t})
        ext = dict(pdata["extruder"])
        if d is not None:
            ext["nozzle_diameter_mm"] = d
        if f is not None:
            ext["filament_diameter_mm"] = f
        pdata["extruder"] = ext
        k = settings.pressure_advance_s
        if k is not None:
            pa = dict(pdata["pressure_advance"])
            pa["k_s"] = k
            pdata["pressure_advance"] = pa
    printer = _validated(pdata, "printer")
    out = replace(machine, printer=printer, hotend=hotend, filament=filament, setup=setup)
    check_machine(out, f"set-up {machine.name!r} with the slicer's settings")
    return out


def resolve_printer(*, setup: str | os.PathLike[str] | None,
                    klipper_config: str | os.PathLike[str] | None = None,
                    settings: SlicerSettings | None = None,
                    config_source: str = "klipper-config") -> PrinterChoice:
    """Decide the printer and set-up of a run (see the module docstring).

    Parameters
    ----------
    setup
        Set-up: built-in name or TOML (default :data:`flowtwin.simulation.DEFAULT_MACHINE`).
    klipper_config
        A Klipper ``printer.cfg`` (a file the user gave, or one written from Moonraker).
    settings
        The slicer's settings, if any.
    config_source
        How ``klipper_config`` was obtained (``"klipper-config"`` or ``"moonraker"``).

    Returns
    -------
    PrinterChoice

    Raises
    ------
    ProfileError
        Bad profiles, or slicer settings that make no valid printer.
    """
    from flowtwin.simulation import DEFAULT_MACHINE

    machine = load_machine(setup or DEFAULT_MACHINE)
    notes: list[str] = []
    if klipper_config is not None:
        from flowtwin.planner.klipper_config import load_printer_cfg

        cfg = load_printer_cfg(klipper_config)   # checked now: a clear error early
        base = _base_printer(machine, Firmware.KLIPPER)
        ex = cfg.extruders[0] if cfg.extruders else None
        if ex is not None:
            # the physics see the nozzle and filament the firmware is configured with
            data = base.model_dump()
            data["extruder"] = {"nozzle_diameter_mm": ex.nozzle_diameter,
                                "filament_diameter_mm": ex.filament_diameter}
            base = _validated(data, "extruder")
        m = _with_physics(machine, base, settings, notes)
        label = (f"Klipper printer.cfg {os.fspath(klipper_config)}" if config_source ==
                 "klipper-config" else f"Klipper configuration read from {config_source}")
        return PrinterChoice(m, Path(klipper_config), config_source if config_source ==
                             "klipper-config" else "moonraker", label, Firmware.KLIPPER,
                             tuple(notes))
    if settings is None:
        m = machine
        return PrinterChoice(m, None, "profile",
                             f"printer profile {m.printer.name!r} ({m.printer.firmware.label})",
                             m.printer.firmware, ("no slicer settings found: the printer "
                                                  "profile decides",))
    fw, note = firmware_of_flavor(settings.flavor, settings.printer_model)
    if note:
        notes.append(note)
    fw = fw or machine.printer.firmware
    base = _base_printer(machine, fw)
    printer = _slicer_printer(base, settings, fw, settings.mode(0), notes)
    m = _with_physics(machine, printer, settings, notes)
    silent = None
    if fw.planner is PlannerFamily.MARLIN and settings.has_silent_mode():
        silent_notes: list[str] = []
        silent = _slicer_printer(base, settings, fw, settings.mode(1), silent_notes)
        silent = _with_physics(machine, silent, settings, silent_notes).printer
    label = (f"limits of the slicer's settings ({settings.source}) on printer profile "
             f"{base.name!r}")
    return PrinterChoice(m, None, f"slicer settings ({settings.source})", label, fw,
                         tuple(notes), silent)
