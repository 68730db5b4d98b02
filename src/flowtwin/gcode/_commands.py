"""What the reader knows about commands: which are events, which are harmless, which
parameters must be numbers, and small helpers for the lines Python interprets."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from flowtwin.gcode.moves import Event

__all__ = [
    "EVENT_CODES",
    "EVENT_SETTERS",
    "HARMLESS_CODES",
    "HEATER_MACROS",
    "IS_EVENT",
    "IS_HARMLESS",
    "IS_UNKNOWN",
    "LETTERS",
    "NUMERIC_PARAMS",
    "Span",
    "event_setters",
    "heater_event",
    "is_rrf_g10",
    "number_param",
]

#: Commands kept as :class:`Event` for the planner and the physics.
EVENT_CODES = frozenset({
    "G4", "G10", "G11", "G28", "G29", "M0", "M1", "M18", "M84", "M104", "M106", "M107",
    "M109", "M140", "M190", "M141", "M191", "M200", "M201", "M203", "M204", "M205",
    "M207", "M208", "M220", "M221", "M400", "M572", "M900", "SET_VELOCITY_LIMIT",
    "SET_PRESSURE_ADVANCE", "ACTIVATE_EXTRUDER", "M82", "M83", "G90", "G91", "G92",
    "G20", "G21",
    # pauses, filament changes, probing and levelling: the firmware stops the head
    "M600", "M601", "M125", "M226", "M420", "M701", "M702", "G30", "G33", "G34", "M25",
})
#: Commands understood without consequence for the twin (not "unknown").
HARMLESS_CODES = frozenset({"G17", "M117", "M73", "M105", "M115", "M110",
                            "M17", "M108", "M113", "M103", "M101"})
#: Parameters that must be numbers, per command.
NUMERIC_PARAMS: dict[str, frozenset[str]] = {
    "G4": frozenset("PS"), "M104": frozenset("ST"), "M109": frozenset("STR"),
    "M140": frozenset("S"), "M190": frozenset("SR"), "M201": frozenset("XYZE"),
    "M203": frozenset("XYZE"), "M204": frozenset("PRTS"), "M205": frozenset("XYZEJBST"),
    "M207": frozenset("SFZ"), "M208": frozenset("SF"), "M220": frozenset("S"),
    "M900": frozenset("K"), "M572": frozenset("SD"), "M200": frozenset("DT"),
    "SET_VELOCITY_LIMIT": frozenset({"ACCEL", "VELOCITY", "SQUARE_CORNER_VELOCITY",
                                     "MINIMUM_CRUISE_RATIO", "ACCEL_TO_DECEL"}),
    "SET_PRESSURE_ADVANCE": frozenset({"ADVANCE", "SMOOTH_TIME"}),
}

#: Klipper commands that set the nozzle temperature without an M104/M109: the start macro
#: slicers call with the first layer's temperature (its body is the printer's; by the
#: common convention it heats and waits), and Klipper's own heater command.
HEATER_MACROS = frozenset({"START_PRINT", "PRINT_START", "SET_HEATER_TEMPERATURE"})
#: Parameter names of the nozzle temperature in start macros, by common use.
_MACRO_TEMP_KEYS = ("EXTRUDER_TEMP", "EXTRUDER_TEMPERATURE", "EXTRUDER", "HOTEND_TEMP",
                    "HOTEND", "NOZZLE_TEMP", "NOZZLE")


def heater_event(code: str, params: dict[str, float | str]
                 ) -> tuple[str, dict[str, float | str], str] | None:
    """The temperature command a Klipper heater macro stands for, or ``None``.

    ``START_PRINT EXTRUDER_TEMP=220`` → ``("M109", {"S": 220.0}, "EXTRUDER_TEMP")``;
    ``SET_HEATER_TEMPERATURE HEATER=extruder1 TARGET=215`` →
    ``("M104", {"S": 215.0, "T": 1.0}, "TARGET")``. A macro without a nozzle temperature,
    or a heater that is not an extruder, gives ``None``. The third item is the parameter
    read (to name it in messages); its value may be text (the caller checks).
    """
    if code == "SET_HEATER_TEMPERATURE":
        heater = str(params.get("HEATER", "")).lower()
        if not heater.startswith("extruder") or "TARGET" not in params:
            return None
        index = heater[len("extruder"):]
        out: dict[str, float | str] = {"S": params["TARGET"]}
        if index:
            if not index.isdigit():
                return None
            out["T"] = float(index)
        return "M104", out, "TARGET"
    for key in _MACRO_TEMP_KEYS:
        if key in params:
            return "M109", {"S": params[key]}, key
    return None


LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
#: Categories of kernel-parsed commands.
IS_EVENT, IS_HARMLESS, IS_UNKNOWN = 0, 1, 2


def event_setters() -> tuple[Callable[..., Any], ...]:
    """``object.__new__`` and the slot setters of :class:`Event`, in field order.

    The reader makes thousands of events per file (one per ``M204``); setting the slots
    directly costs half of the frozen dataclass's ``__init__`` and gives the same object.
    Only valid while :class:`Event` is a plain slotted record of these four fields.
    """
    names = tuple(f.name for f in fields(Event))
    if names != ("move_index", "line", "code", "params") or hasattr(Event, "__post_init__"):
        raise RuntimeError("flowtwin.gcode.moves.Event changed: update _commands.event_setters")
    return (object.__new__, *(getattr(Event, name).__set__ for name in names))


EVENT_SETTERS = event_setters()


@dataclass(frozen=True, slots=True)
class Span:
    """Where a kernel-parsed line is; its text is decoded only for a message."""

    buf: bytes
    start: int
    end: int

    def __str__(self) -> str:
        return self.buf[self.start:self.end].decode("utf-8", "replace").rstrip("\r")


def number_param(params: dict[str, float | str], key: str, default: float) -> float:
    """``params[key]`` when it is a number, else ``default``."""
    value = params.get(key)
    return value if isinstance(value, float) else default


def is_rrf_g10(params: dict[str, float | str]) -> bool:
    """RepRapFirmware's ``G10 P<tool> S<active> R<standby>`` (or offsets), not a retraction."""
    if any(k in params for k in ("P", "R", "L", "X", "Y", "Z", "U", "V", "W")):
        return True
    s = params.get("S")
    return isinstance(s, float) and s > 1.0
