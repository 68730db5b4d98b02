"""Read and plan a G-code file for a printer: the API behind ``flowtwin plan``.

The printer comes from a :class:`~flowtwin.profiles.printer.PrinterProfile` (built-in name,
TOML file or object) or from a Klipper ``printer.cfg``. For Marlin-style firmware the
limits of the profile apply, replaced by the machine limits a PrusaSlicer / OrcaSlicer
header embeds when ``use_slicer_limits`` is set; ``M201``–``M205`` in the G-code then
apply from where they appear, as on the printer.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import BinaryIO

from flowtwin.defaults import DEFAULT_PRINTER
from flowtwin.errors import ProfileError
from flowtwin.firmware import PlannerFamily
from flowtwin.gcode.moves import MoveTable
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.from_profile import klipper_settings, marlin_settings, read_options
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import (
    KlipperSettings,
    klipper_read_options,
    load_printer_cfg,
)
from flowtwin.planner.marlin import MarlinSettings, marlin_settings_from_slicer_config, plan_marlin
from flowtwin.planner.marlin_delta import segment_moves
from flowtwin.planner.timeline import Timeline
from flowtwin.planner.totals import PlanTotals
from flowtwin.profiles.printer import PrinterProfile

__all__ = ["DEFAULT_PRINTER", "PlanResult", "PlanSummary", "load_printer", "metadata_number",
           "plan_for_profile", "plan_gcode", "plan_table"]



@dataclass(slots=True)
class PlanResult:
    """A G-code file read and planned for one printer.

    Attributes
    ----------
    table
        The moves, events and metadata.
    timeline
        Velocity profile of every move and the total time.
    printer
        Name of the printer (profile name or ``printer.cfg`` path).
    settings
        The firmware settings the planner used.
    """

    table: MoveTable
    timeline: Timeline
    printer: str
    settings: KlipperSettings | MarlinSettings
    _totals: PlanTotals | None = field(default=None, init=False, repr=False, compare=False)

    def totals(self) -> PlanTotals:
        """Per-tool, per-feature and per-layer sums of the plan (one compiled pass over the
        moves, computed once)."""
        if self._totals is None:
            tot = PlanTotals()
            tot.add(self.table.moves, self.timeline.phases, self.timeline.dwell_s)
            self._totals = tot
        return self._totals

    def per_layer(self) -> list[dict[str, float | int]]:
        """One row per layer: index, Z (mm), time (s), filament (mm), moves."""
        return self.totals().per_layer(self.table.layer_z)

    def summary(self) -> PlanSummary:
        """The whole-print figures (:class:`PlanSummary`)."""
        t = self.table
        tot = self.totals()
        net = {str(k): w for k, (w, _x) in tot.filament_by_tool().items()}
        extruded = {str(k): x for k, (_w, x) in tot.filament_by_tool().items()}
        by_feature = tot.time_by_feature(t.features)
        n = tot.moves
        ext_written = tot.extruding_written
        layers = tot.layers
        slicer = t.metadata.get("slicer")
        return PlanSummary(
            file=t.source, printer=self.printer, firmware=self.timeline.firmware,
            total_time_s=float(self.timeline.total_time_s), net_filament_mm=net,
            extruded_filament_mm=extruded, moves=int(n), extruding_moves=int(ext_written),
            lines=t.n_lines, layers=int(layers), unknown_commands=dict(t.unknown_commands),
            warnings=len(t.warnings) + len(self.timeline.warnings),
            time_by_feature_s=by_feature, slicer=slicer if isinstance(slicer, str) else None,
            slicer_time_s=metadata_number(t.metadata.get("slicer_time_s")),
            slicer_filament_mm=metadata_number(t.metadata.get("slicer_filament_mm")))


@dataclass(frozen=True, slots=True)
class PlanSummary:
    """The whole-print figures of a plan (the ``--json`` object of ``flowtwin plan``).

    Attributes
    ----------
    file, printer, firmware
        The G-code's name, the printer (profile name or ``printer.cfg``), the firmware.
    total_time_s
        Planned print time, s.
    net_filament_mm, extruded_filament_mm
        Net filament written (E words, firmware retractions left out) and filament
        extruded (after M221) per tool number, mm.
    moves, extruding_moves, lines, layers
        Move rows, extruding rows written in the G-code, lines read, layers.
    unknown_commands
        Commands the reader did not interpret, with counts.
    warnings
        Number of reader and planner warnings.
    time_by_feature_s
        Print time per feature name (dwells as one feature), s.
    slicer, slicer_time_s, slicer_filament_mm
        The slicer and its own time (s) and filament (mm) estimates, where the file says.
    """

    file: str
    printer: str
    firmware: str
    total_time_s: float
    net_filament_mm: Mapping[str, float]
    extruded_filament_mm: Mapping[str, float]
    moves: int
    extruding_moves: int
    lines: int
    layers: int
    unknown_commands: Mapping[str, int]
    warnings: int
    time_by_feature_s: Mapping[str, float]
    slicer: str | None = None
    slicer_time_s: float | None = None
    slicer_filament_mm: float | None = None

    def as_dict(self) -> dict[str, object]:
        """The figures as plain JSON-able values (keys in the ``--json`` order)."""
        return {
            "file": self.file, "printer": self.printer, "firmware": self.firmware,
            "total_time_s": self.total_time_s, "net_filament_mm": dict(self.net_filament_mm),
            "extruded_filament_mm": dict(self.extruded_filament_mm), "moves": self.moves,
            "extruding_moves": self.extruding_moves, "lines": self.lines,
            "layers": self.layers, "unknown_commands": dict(self.unknown_commands),
            "warnings": self.warnings, "time_by_feature_s": dict(self.time_by_feature_s),
            "slicer": self.slicer, "slicer_time_s": self.slicer_time_s,
            "slicer_filament_mm": self.slicer_filament_mm,
        }


def metadata_number(value: object) -> float | None:
    """A metadata number as written (``None`` when absent or not a number)."""
    return value if isinstance(value, float | int) and not isinstance(value, bool) else None


def load_printer(printer: PrinterProfile | str | os.PathLike[str] | None) -> PrinterProfile:
    """A printer profile from an object, a built-in name or a TOML file."""
    from flowtwin.profiles import load_builtin, load_profile

    if isinstance(printer, PrinterProfile):
        return printer
    if printer is None:
        printer = DEFAULT_PRINTER
    text = os.fspath(printer)
    if Path(text).suffix == ".toml" or os.sep in text:
        return load_profile(text, "printer")
    profile = load_builtin(text)
    if not isinstance(profile, PrinterProfile):
        raise ProfileError("not a printer profile", field="printer", value=text,
                           allowed="a printer from `flowtwin profiles list`")
    return profile


def plan_gcode(source: str | os.PathLike[str] | bytes | BinaryIO, *,
               printer: PrinterProfile | str | os.PathLike[str] | None = None,
               klipper_config: str | os.PathLike[str] | None = None,
               use_slicer_limits: bool = False, strict: bool = False) -> PlanResult:
    """Read ``source`` and plan it for a printer.

    Parameters
    ----------
    source
        G-code path (plain or gzip), ``"-"`` for stdin, bytes or a binary stream.
    printer
        Printer profile (object, built-in name or TOML path); default
        :data:`DEFAULT_PRINTER`. Ignored when ``klipper_config`` is given.
    klipper_config
        A Klipper ``printer.cfg`` to plan with instead of a profile.
    use_slicer_limits
        For Marlin-style firmware: take the machine limits from the slicer's embedded
        configuration when the file has them.
    strict
        Unknown commands are errors.

    Returns
    -------
    PlanResult
    """
    if klipper_config is not None:
        ksettings = load_printer_cfg(klipper_config)
        table = read_gcode(source, options=klipper_read_options(ksettings, strict=strict))
        return PlanResult(table, plan_klipper(table, ksettings), os.fspath(klipper_config),
                          ksettings)
    profile = load_printer(printer)
    table = read_gcode(source, options=read_options(profile, strict=strict))
    return plan_for_profile(table, profile, use_slicer_limits=use_slicer_limits)


def plan_for_profile(table: MoveTable, profile: PrinterProfile, *,
                     use_slicer_limits: bool = False) -> PlanResult:
    """Plan a move table read with ``read_options(profile)`` as ``profile``'s firmware would.

    The planning half of :func:`plan_gcode`: a caller that plans one print for several
    printer profiles (another advance factor, say) reads it once and calls this.

    Parameters
    ----------
    table
        The moves, read with :func:`~flowtwin.planner.from_profile.read_options` of
        ``profile`` (not yet segmented for a delta).
    profile
        The printer.
    use_slicer_limits
        As in :func:`plan_gcode`.

    Returns
    -------
    PlanResult
    """
    if profile.firmware.planner is PlannerFamily.KLIPPER:
        ks = klipper_settings(profile)
        return PlanResult(table, plan_klipper(table, ks), profile.name, ks)
    ms = marlin_settings(profile)
    if use_slicer_limits:
        # the slicer describes its machine's limits completely (classic jerk and all): use
        # them as they are; the delta geometry is the printer's
        sl = marlin_settings_from_slicer_config(table.metadata)
        ms = replace(sl, delta=ms.delta) if sl is not None else ms
    if ms.delta is not None:
        table = segment_moves(table, ms.delta)   # Marlin plans a delta's segments
    return PlanResult(table, plan_marlin(table, ms), profile.name, ms)


def plan_table(table: MoveTable, settings: KlipperSettings | MarlinSettings, *,
               printer: str) -> PlanResult:
    """Plan a move table (read, or made in memory) with given firmware settings.

    Parameters
    ----------
    table
        The moves.
    settings
        Klipper's or Marlin's settings (e.g. :attr:`PlanResult.settings` of a plan of the
        same printer).
    printer
        Name of the printer (for the result).
    """
    if isinstance(settings, KlipperSettings):
        return PlanResult(table, plan_klipper(table, settings), printer, settings)
    if settings.delta is not None:
        table = segment_moves(table, settings.delta)   # Marlin plans a delta's segments
    return PlanResult(table, plan_marlin(table, settings), printer, settings)
