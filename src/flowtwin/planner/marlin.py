"""Marlin 2.x motion planner model: trapezoids with look-ahead, classic jerk or JD.

What the model does, per move (Marlin/src/module/planner.cpp, ``_populate_block``;
the G-code side from the Marlin documentation of M201, M203, M204, M205 and M900):

* speed: the requested feed (already × M220 in the move table), raised to M205 S (moves
  with E) or T (without), then scaled down so no axis exceeds its M203 limit — the E
  axis counts with its real (× M221) distance;
* acceleration: M204 P for moves with X/Y/Z and E, T for X/Y/Z without E, R for E-only
  moves; then, except for E-only moves, capped so that no axis exceeds its M201 limit
  (``a · |d_i| / L ≤ amax_i``) and, with ``LIN_ADVANCE`` built in and ``K > 0``, at
  ``E-jerk / (K · e/D)`` for extruding moves with ``e/D ≤ 3``;
* junction speed with the previous move: classic jerk (M205 X Y Z E, two variants, see
  :class:`JerkVariant`) or junction deviation (M205 J), never below the minimum planner
  speed;
* look-ahead: Marlin fixes the exit speed of the block it starts executing with only the
  ``BLOCK_BUFFER_SIZE - 2`` blocks queued behind it, the last of which must be able to
  stop; the reverse and forward passes run on squared speeds
  (:mod:`flowtwin.planner._marlin_kernel` has the equations);
* stops: the planner drains (speed → minimum planner speed) before ``G4``, ``M400``,
  homing, heater waits and other synchronising commands (:data:`SYNC_CODES`), at tool
  changes, at ``M900 K`` changes and after the lines the caller names; ``G4 P<ms>`` /
  ``S<s>`` adds its dwell.

Not modelled: step rounding (``MIN_STEPS_PER_SEGMENT``, integer step rates), the
100 ms first-block delay after an empty buffer (skipped when ≥ 3 moves are queued, as
they are when printing), S-curve acceleration (same durations), input shaping, and a
buffer drained by a slow host (except by the optional ``SLOWDOWN`` rule).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

from flowtwin.errors import GcodeError, ProfileError
from flowtwin.gcode.moves import Event, MoveTable
from flowtwin.planner import _marlin_kernel as kernel
from flowtwin.planner.marlin_delta import SEGMENTED_KEY, MarlinDelta, tower_distances
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline

__all__ = [
    "SETTINGS_CODES",
    "SYNC_CODES",
    "JerkVariant",
    "MarlinSettings",
    "marlin_settings_from_slicer_config",
    "plan_marlin",
]

#: Commands after which Marlin's planner has drained (``planner.synchronize()`` or a wait
#: that blocks the command queue until the moves already queued have run).
SYNC_CODES = frozenset({
    "G4", "M400", "G28", "G29", "G30", "G33", "G34", "M0", "M1", "M25", "M109", "M190",
    "M191", "M125", "M226", "M420", "M600", "M601", "M701", "M702", "M18", "M84",
})

Vec4 = tuple[float, float, float, float]


class JerkVariant(Enum):
    """Which classic-jerk junction rule the firmware uses (``CLASSIC_JERK`` builds)."""

    #: Marlin 1.1 – 2.1.2.x, Prusa firmware and PrusaSlicer's time estimator: coasting /
    #: axis-reversal jerk with the "safe speed" rule (see
    #: :func:`flowtwin.planner._marlin_kernel.junction_classic_legacy`).
    LEGACY = "legacy"
    #: Marlin bugfix-2.1.x after the 2023 CLASSIC_JERK rework: signed per-axis velocity
    #: difference at the shared junction speed.
    REWORKED = "reworked"


def _check_positive(name: str, value: float, *, allow_zero: bool = False) -> None:
    ok = value >= 0.0 if allow_zero else value > 0.0
    if not (ok and np.isfinite(value)):
        raise ProfileError("invalid Marlin setting", field=name, value=value,
                           allowed=">= 0" if allow_zero else "> 0 (finite)")


@dataclass(frozen=True, slots=True)
class MarlinSettings:
    """Motion settings of a Marlin 2.x firmware (defaults: stock ``Configuration.h``).

    Per-axis tuples are ``(X, Y, Z, E)``.

    Attributes
    ----------
    max_feedrate_mm_s
        M203, mm/s.
    max_acceleration_mm_s2
        M201, mm/s².
    print_accel_mm_s2, retract_accel_mm_s2, travel_accel_mm_s2
        M204 P, R, T, mm/s².
    jerk_mm_s
        M205 X Y Z E "classic jerk", mm/s (used when ``junction_deviation_mm`` is None).
    junction_deviation_mm
        M205 J, mm; ``None`` means the firmware is built with ``CLASSIC_JERK``.
    jerk_variant
        Classic-jerk junction rule (:class:`JerkVariant`).
    jd_small_segments
        ``JD_HANDLE_SMALL_SEGMENTS`` (on in stock Marlin).
    minimum_planner_speed_mm_s
        Floor of every junction speed and the exit speed of the last queued block, mm/s.
    min_feedrate_mm_s, min_travel_feedrate_mm_s
        M205 S and T, mm/s.
    min_segment_time_s
        M205 B (given in µs in G-code), s; used only by the ``SLOWDOWN`` option.
    slowdown_moves_queued
        Model Marlin's ``SLOWDOWN`` as if the buffer always held this many moves: a move
        shorter than ``min_segment_time_s`` then takes ``t + 2 (t_min - t) / q``. Marlin
        applies it only while ``2 <= q <= BLOCK_BUFFER_SIZE/2 - 1`` (a host that cannot
        keep up); 0 (default) turns it off.
    block_buffer_size
        ``BLOCK_BUFFER_SIZE`` (look-ahead), ≥ 3; ``None`` plans with unlimited look-ahead
        (as slicer estimators do).
    lin_advance
        Firmware built with ``LIN_ADVANCE``: M900 K is honoured, changing K drains the
        planner, and the acceleration cap ``E-jerk / (K · e/D)`` applies.
    linear_advance_k
        M900 K, s (mm of filament per mm/s of filament speed).
    delta
        A linear delta build (:class:`~flowtwin.planner.marlin_delta.MarlinDelta`): the
        move table must be cut into its segments first
        (:func:`~flowtwin.planner.marlin_delta.segment_moves`); M203, M201 and classic
        jerk then apply to the towers (``max_feedrate_mm_s`` etc. X, Y, Z = towers A, B,
        C). ``None``: X, Y, Z motors.
    """

    max_feedrate_mm_s: Vec4 = (300.0, 300.0, 5.0, 25.0)
    max_acceleration_mm_s2: Vec4 = (3000.0, 3000.0, 100.0, 10000.0)
    print_accel_mm_s2: float = 3000.0
    retract_accel_mm_s2: float = 3000.0
    travel_accel_mm_s2: float = 3000.0
    jerk_mm_s: Vec4 = (10.0, 10.0, 0.3, 5.0)
    junction_deviation_mm: float | None = 0.013
    jerk_variant: JerkVariant = JerkVariant.LEGACY
    jd_small_segments: bool = True
    minimum_planner_speed_mm_s: float = 0.05
    min_feedrate_mm_s: float = 0.0
    min_travel_feedrate_mm_s: float = 0.0
    min_segment_time_s: float = 0.02
    slowdown_moves_queued: int = 0
    block_buffer_size: int | None = 16
    lin_advance: bool = False
    linear_advance_k: float = 0.0
    delta: MarlinDelta | None = None

    def __post_init__(self) -> None:
        for name in ("max_feedrate_mm_s", "max_acceleration_mm_s2", "jerk_mm_s"):
            vec = getattr(self, name)
            if len(vec) != 4:
                raise ProfileError("needs 4 values (X, Y, Z, E)", field=name, value=vec)
            for v in vec:
                _check_positive(name, float(v), allow_zero=(name == "jerk_mm_s"))
        for name in ("print_accel_mm_s2", "retract_accel_mm_s2", "travel_accel_mm_s2",
                     "minimum_planner_speed_mm_s"):
            _check_positive(name, getattr(self, name))
        for name in ("min_feedrate_mm_s", "min_travel_feedrate_mm_s", "min_segment_time_s",
                     "linear_advance_k"):
            _check_positive(name, getattr(self, name), allow_zero=True)
        if self.junction_deviation_mm is not None:
            _check_positive("junction_deviation_mm", self.junction_deviation_mm)
        if not isinstance(self.jerk_variant, JerkVariant):
            raise ProfileError("unknown classic-jerk variant", field="jerk_variant",
                               value=self.jerk_variant,
                               allowed=", ".join(v.value for v in JerkVariant))
        if self.slowdown_moves_queued != 0 and self.slowdown_moves_queued < 2:
            raise ProfileError("SLOWDOWN needs at least 2 queued moves",
                               field="slowdown_moves_queued",
                               value=self.slowdown_moves_queued, allowed="0 (off) or >= 2")
        if self.block_buffer_size is not None and self.block_buffer_size < 3:
            raise ProfileError("look-ahead buffer too small", field="block_buffer_size",
                               value=self.block_buffer_size, allowed=">= 3 or None")

    @property
    def classic_jerk(self) -> bool:
        """True when the firmware uses classic jerk rather than junction deviation."""
        return self.junction_deviation_mm is None

    def updated_from_event(self, event: Event, *, source: str | None = None
                           ) -> MarlinSettings:
        """Settings after one G-code command (M201, M203, M204, M205, M900; others: self).

        Parameters
        ----------
        event
            The command; parameters Marlin ignores (e.g. ``M205 J`` on a classic-jerk
            build, ``M201 F``) leave the settings unchanged.
        source
            File name for error messages.

        Raises
        ------
        GcodeError
            A limit that would stall the printer (zero or negative acceleration or feed
            rate, negative jerk); the message names the line and parameter.
        """
        return self.updated_from_events((event,), source=source)

    def updated_from_events(self, events: Iterable[Event], *, source: str | None = None
                            ) -> MarlinSettings:
        """Settings after every command of ``events`` in order (see
        :meth:`updated_from_event`)."""
        row = self.param_row()
        for ev in events:
            if ev.code in SETTINGS_CODES:
                _apply_event(row, ev, self, source)
        return self if row == self.param_row() else self._with_row(row)

    def param_row(self) -> list[float]:
        """The G-code-settable values as one row of the kernel's parameter table."""
        row = [0.0] * kernel.N_PARAMS
        row[kernel.P_VMAX:kernel.P_VMAX + 4] = self.max_feedrate_mm_s
        row[kernel.P_AMAX:kernel.P_AMAX + 4] = self.max_acceleration_mm_s2
        row[kernel.P_ACCEL_P] = self.print_accel_mm_s2
        row[kernel.P_ACCEL_R] = self.retract_accel_mm_s2
        row[kernel.P_ACCEL_T] = self.travel_accel_mm_s2
        row[kernel.P_JERK:kernel.P_JERK + 4] = self.jerk_mm_s
        row[kernel.P_JD] = self.junction_deviation_mm or 0.0
        row[kernel.P_MIN_FEED] = self.min_feedrate_mm_s
        row[kernel.P_MIN_TRAVEL] = self.min_travel_feedrate_mm_s
        row[kernel.P_MIN_SEG_T] = self.min_segment_time_s
        row[kernel.P_LA_K] = self.linear_advance_k
        return row

    def _with_row(self, row: Sequence[float]) -> MarlinSettings:
        """Inverse of :meth:`param_row` (build options are kept from ``self``)."""
        def vec(c: int) -> Vec4:
            return (row[c], row[c + 1], row[c + 2], row[c + 3])
        return replace(
            self, max_feedrate_mm_s=vec(kernel.P_VMAX), max_acceleration_mm_s2=vec(kernel.P_AMAX),
            print_accel_mm_s2=row[kernel.P_ACCEL_P], retract_accel_mm_s2=row[kernel.P_ACCEL_R],
            travel_accel_mm_s2=row[kernel.P_ACCEL_T], jerk_mm_s=vec(kernel.P_JERK),
            junction_deviation_mm=None if self.classic_jerk else row[kernel.P_JD],
            min_feedrate_mm_s=row[kernel.P_MIN_FEED],
            min_travel_feedrate_mm_s=row[kernel.P_MIN_TRAVEL],
            min_segment_time_s=row[kernel.P_MIN_SEG_T], linear_advance_k=row[kernel.P_LA_K])


_INF = float("inf")

#: Commands that change the planner settings.
SETTINGS_CODES = frozenset({"M201", "M203", "M204", "M205", "M900"})


def _number(event: Event, letter: str, source: str | None, *, positive: bool) -> float | None:
    """Numeric value of a parameter, ``None`` when absent or given without a value."""
    raw = event.params.get(letter)
    if raw is None:
        return None
    if raw.__class__ is float and (raw > 0.0 if positive else raw >= 0.0) and raw < _INF:
        return raw                       # the common case, checked first for speed
    if raw == "":
        return None
    if isinstance(raw, str):
        try:
            raw = float(raw)
        except ValueError:
            raise GcodeError(f"{event.code} {letter} is not a number", source=source,
                             line=event.line, field=f"{event.code} {letter}",
                             value=raw) from None
    value = float(raw)
    ok = (value > 0.0 if positive else value >= 0.0) and np.isfinite(value)
    if not ok:
        raise GcodeError(f"{event.code} {letter} would stall the Marlin planner",
                         source=source, line=event.line, field=f"{event.code} {letter}",
                         value=value, allowed="> 0" if positive else ">= 0")
    return value


def _set_axes(row: list[float], col: int, event: Event, source: str | None, *,
              positive: bool) -> None:
    for ax, letter in enumerate("XYZE"):
        v = _number(event, letter, source, positive=positive)
        if v is not None:
            row[col + ax] = v


def _set(row: list[float], col: int, event: Event, letter: str, source: str | None, *,
         positive: bool, scale: float = 1.0) -> None:
    v = _number(event, letter, source, positive=positive)
    if v is not None:
        row[col] = v * scale


def _apply_event(row: list[float], ev: Event, build: MarlinSettings, source: str | None
                 ) -> str | None:
    """Apply a settings command to a parameter row in place; say what Marlin ignores.

    ``build`` supplies the firmware build options (classic jerk or JD, LIN_ADVANCE).
    Marlin documentation: M201 X Y Z E (mm/s²), M203 X Y Z E (mm/s), M204 S (sets P and
    T), P, R, T (mm/s²), M205 S T (mm/s), B (µs), X Y Z E (jerk, mm/s, CLASSIC_JERK
    builds) or J (mm, junction-deviation builds), M900 K (0–10, LIN_ADVANCE builds).
    """
    code = ev.code
    if code == "M201":
        _set_axes(row, kernel.P_AMAX, ev, source, positive=True)
        return "M201 F/S (XY frequency limit) not modelled" if (
            "F" in ev.params or "S" in ev.params) else None
    if code == "M203":
        _set_axes(row, kernel.P_VMAX, ev, source, positive=True)
        return None
    if code == "M204":
        legacy = _number(ev, "S", source, positive=True)
        if legacy is not None:
            row[kernel.P_ACCEL_P] = row[kernel.P_ACCEL_T] = legacy
        _set(row, kernel.P_ACCEL_P, ev, "P", source, positive=True)
        _set(row, kernel.P_ACCEL_R, ev, "R", source, positive=True)
        _set(row, kernel.P_ACCEL_T, ev, "T", source, positive=True)
        return None
    if code == "M205":
        _set(row, kernel.P_MIN_FEED, ev, "S", source, positive=False)
        _set(row, kernel.P_MIN_TRAVEL, ev, "T", source, positive=False)
        _set(row, kernel.P_MIN_SEG_T, ev, "B", source, positive=False, scale=1e-6)
        has_jerk = any(k in ev.params for k in "XYZE")
        if build.classic_jerk:
            _set_axes(row, kernel.P_JERK, ev, source, positive=False)
            return "M205 J ignored: firmware built with CLASSIC_JERK" if (
                "J" in ev.params) else None
        _set(row, kernel.P_JD, ev, "J", source, positive=True)
        return "M205 X/Y/Z/E ignored: firmware uses junction deviation" if has_jerk else None
    if code == "M900":
        if not build.lin_advance:
            return "M900 ignored: firmware built without LIN_ADVANCE"
        k = _number(ev, "K", source, positive=False)
        if k is not None and k > 10.0:
            return "M900 K out of range (0-10) ignored"
        if k is not None:
            row[kernel.P_LA_K] = k
        return None
    return None


# ------------------------------------------------------------------ slicer config ---

_LIMIT_KEYS: dict[str, tuple[str, ...]] = {
    "max_feedrate_mm_s": ("machine_max_feedrate_{}", "machine_max_speed_{}"),
    "max_acceleration_mm_s2": ("machine_max_acceleration_{}",),
    "jerk_mm_s": ("machine_max_jerk_{}",),
}
_SCALAR_KEYS = {
    "print_accel_mm_s2": "machine_max_acceleration_extruding",
    "retract_accel_mm_s2": "machine_max_acceleration_retracting",
    "travel_accel_mm_s2": "machine_max_acceleration_travel",
    "min_feedrate_mm_s": "machine_min_extruding_rate",
    "min_travel_feedrate_mm_s": "machine_min_travel_rate",
}


def _config_float(config: Mapping[str, object], key: str, *, allow_zero: bool
                  ) -> float | None:
    """First value of a slicer option (``"4000,2500"`` → 4000: normal, not stealth mode)."""
    raw = config.get(key)
    if raw is None:
        return None
    text = str(raw).split(",")[0].strip().strip('"')
    if text == "":
        return None
    try:
        value = float(text)
    except ValueError:
        raise ProfileError("slicer machine limit is not a number", field=key,
                           value=raw) from None
    if not (np.isfinite(value) and (value >= 0.0 if allow_zero else value > 0.0)):
        raise ProfileError("slicer machine limit out of range", field=key, value=raw,
                           allowed=">= 0" if allow_zero else "> 0")
    return value


def marlin_settings_from_slicer_config(metadata: Mapping[str, object], *,
                                       base: MarlinSettings | None = None
                                       ) -> MarlinSettings | None:
    """Marlin settings from the machine limits a PrusaSlicer / OrcaSlicer / Bambu Studio
    file embeds in its config block.

    Parameters
    ----------
    metadata
        ``MoveTable.metadata`` (the config is read from its ``"slicer_config"`` entry) or
        the config mapping itself (``key → raw string``).
    base
        Settings for whatever the config does not give; defaults to
        :class:`MarlinSettings` with classic jerk (slicers describe classic-jerk machines).

    Returns
    -------
    MarlinSettings or None
        ``None`` when the config lists no machine limit, or says the limits are ignored
        (``machine_limits_usage = ignore``). Comma lists (normal, stealth) use the first
        value. ``machine_max_junction_deviation`` > 0 (OrcaSlicer) selects junction
        deviation; a zero or missing travel acceleration falls back to the extruding one.

    Raises
    ------
    ProfileError
        A limit that is not a number, or out of range (names the key).
    """
    raw_config = metadata.get("slicer_config", metadata)
    if not isinstance(raw_config, Mapping):
        raise ProfileError("slicer_config is not a mapping", field="slicer_config",
                           value=type(raw_config).__name__)
    config: Mapping[str, object] = raw_config
    if not any(str(k).startswith("machine_max_") for k in config):
        return None
    if str(config.get("machine_limits_usage", "")).strip() == "ignore":
        return None
    s = base or MarlinSettings(junction_deviation_mm=None)
    vecs = {name: list(getattr(s, name)) for name in _LIMIT_KEYS}
    for name, patterns in _LIMIT_KEYS.items():
        for ax, letter in enumerate("xyze"):
            for pattern in patterns:
                v = _config_float(config, pattern.format(letter),
                                  allow_zero=(name == "jerk_mm_s"))
                if v is not None:
                    vecs[name][ax] = v
                    break
    scalars = {name: _config_float(config, key, allow_zero=name != "print_accel_mm_s2")
               for name, key in _SCALAR_KEYS.items()}
    p = scalars["print_accel_mm_s2"] or s.print_accel_mm_s2
    travel = scalars["travel_accel_mm_s2"]
    jd = _config_float(config, "machine_max_junction_deviation", allow_zero=True)

    def pick(name: str) -> float:
        v = scalars[name]
        return getattr(s, name) if v is None else v
    retract = scalars["retract_accel_mm_s2"]
    return replace(
        s, max_feedrate_mm_s=tuple(vecs["max_feedrate_mm_s"]),
        max_acceleration_mm_s2=tuple(vecs["max_acceleration_mm_s2"]),
        jerk_mm_s=tuple(vecs["jerk_mm_s"]), print_accel_mm_s2=p,
        retract_accel_mm_s2=retract if retract else s.retract_accel_mm_s2,
        travel_accel_mm_s2=travel if travel else p,
        min_feedrate_mm_s=pick("min_feedrate_mm_s"),
        min_travel_feedrate_mm_s=pick("min_travel_feedrate_mm_s"),
        junction_deviation_mm=jd if jd else s.junction_deviation_mm)


# ------------------------------------------------------------------------ planner ---

def _dwell_s(ev: Event, source: str | None) -> float:
    """G4 dwell in s (Marlin: ``S`` seconds wins over ``P`` milliseconds)."""
    s = _number(ev, "S", source, positive=False)
    if s is not None:
        return s
    p = _number(ev, "P", source, positive=False)
    return 0.0 if p is None else p * 1e-3


def _motor_distances(table: MoveTable, settings: MarlinSettings) -> np.ndarray:
    """Tower distances of a delta's segments, or an empty ``(0, 3)`` for X, Y, Z motors."""
    if settings.delta is None:
        return np.zeros((0, 3))
    if table.metadata.get(SEGMENTED_KEY) != settings.delta.segments_per_second:
        raise GcodeError("a Marlin delta plans the segments it cuts every move into: pass "
                         "the table through flowtwin.planner.marlin_delta.segment_moves "
                         "first", source=table.source, field="delta",
                         value=table.metadata.get(SEGMENTED_KEY),
                         allowed=f"a table segmented at {settings.delta.segments_per_second:g}"
                         " segments/s")
    return tower_distances(table, settings.delta)


def plan_marlin(table: MoveTable, settings: MarlinSettings, *,
                stop_after_lines: Sequence[int] = ()) -> Timeline:
    """Plan a move table as Marlin 2.x would execute it.

    Parameters
    ----------
    table
        Moves (``n`` rows) and events from the G-code reader. M201/M203/M204/M205/M900
        events change the settings from the move they precede on.
    settings
        Firmware settings in force before the first line.
    stop_after_lines
        Source lines after which the toolhead must come to a stop (the planner drains
        after the last move that comes from a line ≤ each of them); the print time of
        each stop is in :attr:`Timeline.stop_times_s` (line 0 = before the first line).

    Returns
    -------
    Timeline
        ``firmware="marlin"``; one phase row per move (zero-length moves take no time),
        G4 dwells in ``dwell_s``, settings commands Marlin ignores in ``warnings``, the
        source line of each move in ``lines``. Totals per layer and feature:
        :func:`~flowtwin.planner.timeline.time_by_layer`,
        :func:`~flowtwin.planner.timeline.time_by_feature`.

    Raises
    ------
    GcodeError
        A move with motion but no positive feed rate, or a settings command that would
        stall the planner (names the file and line).
    """
    moves = table.moves
    n = len(table)
    source = table.source
    stop_before = np.zeros(n + 1, dtype=np.bool_)
    dwell_before = np.zeros(n + 1)
    dwells: list[tuple[int, float, str]] = []
    dwell_lines: list[int] = []
    notes: dict[str, list[int]] = {}
    rows = [settings.param_row()]
    change_at = [0]
    for ev in table.events:
        mi = min(max(ev.move_index, 0), n)
        code = ev.code
        if code in SYNC_CODES:
            if code in ("M18", "M84") and ev.params and set(ev.params) <= {"S"}:
                continue                      # M84 S<timeout> only sets the idle timeout
            stop_before[mi] = True
            if code == "G4":
                t = _dwell_s(ev, source)
                dwell_before[mi] += t
                dwells.append((mi, t, f"G4 line {ev.line}"))
                dwell_lines.append(ev.line)
        elif code in SETTINGS_CODES:
            row = rows[-1].copy()
            note = _apply_event(row, ev, settings, source)
            if note is not None:
                notes.setdefault(note, []).append(ev.line)
            if row != rows[-1]:
                if row[kernel.P_LA_K] != rows[-1][kernel.P_LA_K]:
                    stop_before[mi] = True    # M900 K change: planner.synchronize()
                rows.append(row)
                change_at.append(mi)
    lines = np.asarray(moves["line"], dtype=np.int32)
    stop_at: dict[int, int] = {}
    if stop_after_lines:
        ordered = bool(np.all(lines[1:] >= lines[:-1]))
        for line in stop_after_lines:
            k = (int(np.searchsorted(lines, line, side="right")) if ordered
                 else int(np.count_nonzero(lines <= line)))
            stop_before[k] = True
            stop_at[int(line)] = k

    starts = np.asarray(change_at, dtype=np.int64)
    if np.all(starts[1:] >= starts[:-1]):
        state = np.repeat(np.arange(len(rows), dtype=np.int32),
                          np.diff(np.append(starts, n)))
    else:   # events out of file order: the last one listed before a move wins
        state = (np.searchsorted(starts, np.arange(n), side="right") - 1).astype(np.int32)
    params = np.array(rows, dtype=np.float64)
    phases = np.zeros(n, dtype=PHASE_DTYPE)
    total, bad = kernel.plan_kernel(
        moves, np.asarray(table.start_xyze[:3], dtype=np.float64), state, params,
        stop_before, dwell_before, not settings.classic_jerk,
        settings.jerk_variant is JerkVariant.LEGACY, settings.jd_small_segments,
        settings.lin_advance, settings.minimum_planner_speed_mm_s,
        settings.block_buffer_size or 0, settings.slowdown_moves_queued, phases,
        _motor_distances(table, settings))
    if bad >= 0:
        raise GcodeError("move without a positive feed rate", source=source,
                         line=int(moves["line"][bad]), field="F",
                         value=float(moves["feed_mm_s"][bad]), allowed="> 0 mm/min")
    warnings = [f"{note}: {len(where)}× (first at line {where[0]})"
                for note, where in notes.items()]
    # Time of each requested stop: end of the moves up to that line plus the dwells of
    # lines up to it that sit between those moves and the next one.
    stop_times: dict[int, float] = {}
    for line, k in stop_at.items():
        t = 0.0
        if k > 0:
            last = phases[k - 1]
            t = float(last["t_start"]) + float(last["accel_t"]) + float(
                last["cruise_t"]) + float(last["decel_t"])
        t += sum(d[1] for d, dl in zip(dwells, dwell_lines, strict=True)
                 if d[0] == k and dl <= line)
        stop_times[line] = t
    return Timeline(phases=phases, dwell_s=dwells, total_time_s=float(total),
                    firmware="marlin", warnings=warnings, stop_times_s=stop_times,
                    lines=lines)

