"""Streaming G-code reader: text (path, gzip, .bgcode, stdin, bytes) → :class:`MoveTable`.

The frequent commands are executed by a numba kernel over raw bytes
(:mod:`flowtwin.gcode._kernel`); everything else (comments, events, unknown and rare
commands) is interpreted here in file order. Input is read in chunks that end on a line
break, so :func:`iter_move_chunks` streams files of any size in bounded memory, and
:func:`read_gcode` concatenates the chunks.

Semantics follow the firmware where they agree (Klipper and Marlin): ``F`` is mm/min;
``G91`` makes E relative as well; ``G92`` sets G-code coordinates without moving; ``G28``
puts the named axes (all when none is named) at :attr:`ReadOptions.home_xyz`; ``M220``
scales feed rates, ``M221`` extrusion; ``T<n>`` selects tool ``n`` (pseudo-tools such as
``T255`` or ``T1000`` are kept as numbers); ``G10``/``G11`` are firmware retractions
(``M207``/``M208`` settings) unless they carry RepRapFirmware tool parameters
(``G10 P0 S195 R160`` sets temperatures); ``M200 D<d>`` switches E to mm³, and so does
a CuraEngine volumetric flavor named in the header (``;FLAVOR:UltiGCode``,
``;FLAVOR:Marlin(Volumetric)``), from the first line.
"""

from __future__ import annotations

import gzip
import math
import os
import sys
from collections.abc import Iterator
from dataclasses import replace
from typing import BinaryIO

import numpy as np

from flowtwin.errors import GcodeError
from flowtwin.gcode import _kernel as kernel
from flowtwin.gcode._arc import MAX_ARC_SEGMENTS
from flowtwin.gcode._columns import fill_columns
from flowtwin.gcode._commands import (
    EVENT_CODES,
    EVENT_SETTERS,
    HARMLESS_CODES,
    HEATER_MACROS,
    IS_EVENT,
    IS_HARMLESS,
    IS_UNKNOWN,
    LETTERS,
    NUMERIC_PARAMS,
    Span,
    heater_event,
    is_rrf_g10,
    number_param,
)
from flowtwin.gcode._rows import _Rows
from flowtwin.gcode.flavors import check_extrusion_axis, volumetric_flavor
from flowtwin.gcode.inputs import DEFAULT_CHUNK_BYTES, line_chunks, open_source
from flowtwin.gcode.metadata import CommentInterpreter
from flowtwin.gcode.moves import Event, MoveKind, MoveTable
from flowtwin.gcode.options import FirmwareRetraction, ReadOptions
from flowtwin.gcode.words import parse_line

__all__ = ["FirmwareRetraction", "ReadOptions", "iter_move_chunks", "read_gcode"]

# ------------------------------------------------------------------------ the reader ---

class _Reader:
    """State of one read across chunks."""

    def __init__(self, name: str, options: ReadOptions, *, accumulate: bool = False) -> None:
        self.name = name
        self.options = options
        self.accumulate = accumulate
        self.rows: _Rows | None = None
        self._offset = 0
        s = np.zeros(kernel.N_STATE)
        s[kernel.S_X:kernel.S_Z + 1] = options.start_xyz
        s[kernel.S_FEED] = 25.0  # 1500 mm/min until the file says otherwise
        s[kernel.S_SPEED_FACTOR] = 1.0
        s[kernel.S_FLOW] = 1.0
        s[kernel.S_ABS_XYZ] = 1.0
        s[kernel.S_ABS_E] = 1.0
        s[kernel.S_UNIT] = 1.0
        s[kernel.S_E_FACTOR] = 1.0
        s[kernel.S_HOME_X:kernel.S_HOME_Z + 1] = options.home_xyz
        if options.arc_segment_mm is not None:
            s[kernel.S_ARC_MODE] = 0.0
            s[kernel.S_ARC_PARAM] = options.arc_segment_mm
        else:
            s[kernel.S_ARC_MODE] = 1.0
            s[kernel.S_ARC_PARAM] = options.arc_tolerance_mm
        s[kernel.S_PLANE] = 17.0
        self.state = s
        self.retraction = options.firmware_retraction
        self.retracted = False
        self.comments = CommentInterpreter()
        self.unknown: dict[str, int] = {}
        self._macro_noted = False
        self._codes: dict[int, tuple[str, tuple[str, ...], int]] = {}
        self.warnings: list[str] = []
        self.n_moves = 0            # moves emitted in earlier chunks
        self.e_acc = np.zeros(65536)  # running E per tool (int16(tool) + 32768)
        self.feature = -1
        self.layer = -1
        self.layer_z: list[float] = []
        self.max_extrude_z = -math.inf
        self.last_byte_newline = True
        self.rows_per_byte = 1.0 / 20.0  # rows per byte of G-code, learnt chunk by chunk
        self.bytes_done = 0              # bytes of the chunks already read
        self.total_bytes = 0             # size of the whole input when known, else 0

    # -- errors ------------------------------------------------------------------------
    def _kernel_error(self, buf: bytes, pos: int) -> GcodeError:
        line = int(self.state[kernel.S_ERR_LINE])
        end = buf.find(b"\n", pos)
        text = buf[pos: end if end >= 0 else len(buf)].decode("utf-8", "replace").rstrip("\r")
        code = int(self.state[kernel.S_ERR_CODE])
        known = {kernel.ERR_CHECKSUM: ("checksum does not match the line", None,
                                  "'*' followed by the XOR of all bytes before it"),
                 kernel.ERR_ARC: ("arc needs I/J (centre offset) or an R at least half the chord",
                             None, None),
                 kernel.ERR_ARC_HUGE: ("arc too long: a broken I/J or R", None,
                                  f"<= {MAX_ARC_SEGMENTS} segments"),
                 kernel.ERR_FEED: ("feed rate must be positive", "F", "F > 0 (mm/min)")}
        if code in known:
            message, field_name, allowed = known[code]
            return GcodeError(message, source=self.name, line=line, field=field_name,
                              value=text, allowed=allowed)
        # a malformed number: let the exact parser name the word
        parse_line(text, source=self.name, line=line, numeric=frozenset("XYZEFIJRKPS"))
        return GcodeError("malformed word", source=self.name, line=line, value=text,
                          allowed="letter followed by a decimal number, e.g. X10.5")

    # -- lines the kernel hands over ---------------------------------------------------
    def _python_line(self, text: str, line: int, rows: _Rows) -> None:
        parsed = parse_line(text, source=self.name, line=line)
        code, p = parsed.code, parsed.params
        s = self.state
        if code in ("G0", "G1", "G2", "G3"):
            if code in ("G2", "G3") and s[kernel.S_PLANE] != 17.0:
                raise GcodeError(f"arcs in the G{int(s[kernel.S_PLANE])} plane are not supported",
                                 source=self.name, line=line, value=text,
                                 allowed="G17 (XY plane) arcs")
            # malformed parameters of a move (kernel said so): name them
            parse_line(text, source=self.name, line=line, numeric=frozenset("XYZEFIJR"))
            raise GcodeError("malformed move", source=self.name, line=line, value=text)
        if code.startswith("T") and code[1:].isdigit():
            s[kernel.S_TOOL] = float(code[1:])
            self._event(Event(self._offset + rows.n, line, code, p))
            return
        if code == "G28":
            axes = [a for a in "XYZ" if a in p]
            for axis in axes or ["X", "Y", "Z"]:
                idx = "XYZ".index(axis)
                s[kernel.S_X + idx] = s[kernel.S_HOME_X + idx]
        if code in ("G18", "G19"):
            s[kernel.S_PLANE] = float(code[1:])
            return
        if code == "G10" and self.retraction is not None and not is_rrf_g10(p):
            if not self.retracted:
                self._fw_retract(line, rows, retract=True)
            return
        if code == "G11" and self.retraction is not None:
            if self.retracted:
                self._fw_retract(line, rows, retract=False)
            return
        if code in ("M207", "M208") and self.retraction is not None:
            self._check_numeric(code, p, line, text)
            r = self.retraction
            if code == "M207":
                r = replace(r, length_mm=number_param(p, "S", r.length_mm),
                            speed_mm_s=number_param(p, "F", r.speed_mm_s * 60.0) / 60.0,
                            z_hop_mm=number_param(p, "Z", r.z_hop_mm))
            else:
                r = replace(r, extra_unretract_mm=number_param(p, "S", r.extra_unretract_mm),
                            unretract_speed_mm_s=number_param(
                                p, "F", r.unretract_speed_mm_s * 60) / 60)
            self.retraction = r
        elif code == "M200":
            self._check_numeric(code, p, line, text)
            d = number_param(p, "D", self.options.filament_diameter_mm)
            s[kernel.S_E_FACTOR] = 1.0 / (math.pi * d * d / 4.0) if d > 0 else 1.0
        elif code == "M220":
            value = p.get("S")
            if isinstance(value, float) and not value > 0:
                raise GcodeError("M220 speed factor must be positive", source=self.name,
                                 line=line, field="S", value=value, allowed="S > 0 (%)")
        elif code == "M221":
            value = p.get("S")
            tool = p.get("T")
            if isinstance(value, float) and (tool is None or tool == s[kernel.S_TOOL]):
                if not value > 0:
                    raise GcodeError("M221 flow must be positive", source=self.name, line=line,
                                     field="S", value=value, allowed="S > 0 (%)")
                s[kernel.S_FLOW] = value / 100.0
            else:
                self.warnings.append(f"{self.name}:{line}: '{text.strip()}' does not set the "
                                     "flow of the active tool; ignored")
        self._record(parsed.code, p, parsed.comment, line, self._offset + rows.n, text)

    def _check_numeric(self, code: str, params: dict[str, float | str], line: int,
                       text: str | Span) -> None:
        need = NUMERIC_PARAMS.get(code, frozenset())
        for key, value in params.items():
            if key in need and not isinstance(value, float):
                raise GcodeError(f"{code} parameter {key} is not a number", source=self.name,
                                 line=line, field=key, value=value or str(text).strip(),
                                 allowed="a finite decimal number")

    def _fw_retract(self, line: int, rows: _Rows, *, retract: bool) -> None:
        r = self.retraction
        assert r is not None
        s = self.state
        tool = int(s[kernel.S_TOOL])
        x, y, z = float(s[kernel.S_X]), float(s[kernel.S_Y]), float(s[kernel.S_Z])
        base = int(MoveKind.FW_RETRACT)
        if retract:
            if r.length_mm > 0:
                rows.add(line, tool, (x, y, z), -r.length_mm, r.speed_mm_s, float(s[kernel.S_FLOW]),
                         base | MoveKind.RETRACT, self.e_acc)
            if r.z_hop_mm > 0:
                rows.add(line, tool, (x, y, z + r.z_hop_mm), 0.0, r.speed_mm_s,
                         float(s[kernel.S_FLOW]), base | MoveKind.TRAVEL | MoveKind.Z, self.e_acc)
                s[kernel.S_Z] = z + r.z_hop_mm
            self.retracted = True
        else:
            if r.z_hop_mm > 0:
                rows.add(line, tool, (x, y, z - r.z_hop_mm), 0.0, r.unretract_speed_mm_s,
                         float(s[kernel.S_FLOW]), base | MoveKind.TRAVEL | MoveKind.Z, self.e_acc)
                s[kernel.S_Z] = z - r.z_hop_mm
            amount = r.length_mm + r.extra_unretract_mm
            if amount > 0:
                rows.add(line, tool, (x, y, float(s[kernel.S_Z])), amount, r.unretract_speed_mm_s,
                         float(s[kernel.S_FLOW]), base | MoveKind.EXTRUDE, self.e_acc)
            self.retracted = False

    # -- recorded lines ------------------------------------------------------------------
    def _event(self, event: Event) -> None:
        self.events.append(event)

    def _record(self, code: str, params: dict[str, float | str], comment: str, line: int,
                move_index: int, text: str | Span, *, checked: bool = False) -> None:
        if not code:
            self.comments.feed(comment, move_index, line)
            return
        if code in EVENT_CODES or (code.startswith("T") and code[1:].isdigit()):
            if not checked:  # kernel-parsed commands hold numbers only
                self._check_numeric(code, params, line, text)
            self.events.append(Event(move_index, line, code, params))
        elif code in HEATER_MACROS and (heat := heater_event(code, params)) is not None:
            self._heater_macro(code, heat, line, move_index, text)
        elif code not in HARMLESS_CODES:
            if self.options.strict:
                raise GcodeError(f"unknown command {code}", source=self.name, line=line,
                                 value=str(text).strip(), allowed="commands flowtwin interprets "
                                 "(run without --strict to count and skip unknown ones)")
            self.unknown[code] = self.unknown.get(code, 0) + 1

    def _heater_macro(self, code: str, heat: tuple[str, dict[str, float | str], str],
                      line: int, move_index: int, text: str | Span) -> None:
        """A Klipper macro that sets the nozzle temperature, kept as the M104/M109 it means."""
        m_code, m_params, key = heat
        value = m_params["S"]
        if not isinstance(value, float) or not 0.0 <= value <= 1000.0:
            raise GcodeError(f"{code} {key} is not a temperature", source=self.name,
                             line=line, field=key, value=str(value),
                             allowed="a number of °C, 0–1000")
        self.events.append(Event(move_index, line, m_code, m_params))
        if not self._macro_noted:
            self._macro_noted = True
            self.warnings.append(f"{self.name}:{line}: {str(text).strip()} read as "
                                 f"{m_code} S{value:g} (the macro's body is the printer's: "
                                 "the twin takes the nozzle temperature it is given)")

    def _code_info(self, key: int) -> tuple[str, tuple[str, ...], int]:
        """Command name, parameter letters and category of a kernel-parsed command."""
        info = self._codes.get(key)
        if info is None:
            code_id, mask = divmod(key, 1 << kernel.KEY_SHIFT)
            code = f"{chr(code_id // 1_000_000)}{code_id % 1_000_000}"
            letters = tuple(LETTERS[j] for j in range(26) if mask >> j & 1)
            if code in EVENT_CODES or (code.startswith("T") and code[1:].isdigit()):
                category = IS_EVENT
            else:
                category = IS_HARMLESS if code in HARMLESS_CODES else IS_UNKNOWN
            info = self._codes[key] = (code, letters, category)
        return info

    def _other_lines(self, buf: bytes, rows: _Rows) -> None:
        """Interpret, in file order, the lines the kernel recorded for Python."""
        n = rows.n_other
        if not n:
            return
        feed = self.comments.feed
        base = self._offset
        append_event = self.events.append
        codes = self._codes
        flat = rows.vals[:rows.n_vals].tolist()
        new, set_index, set_line, set_code, set_params = EVENT_SETTERS
        numeric, comment, event_category = kernel.OTHER_NUMERIC, kernel.OTHER_COMMENT, IS_EVENT
        # one list per column, not one per row: n small lists would each be tracked by the
        # garbage collector and set off a full collection over everything alive (~45 ms on a
        # 180 k-line file)
        for lineno, start, end, move_index, kind, key, at in zip(*rows.other[:n].T.tolist(),
                                                                  strict=True):
            if kind == numeric:  # parsed by the kernel: no text to look at
                code, letters, category = codes.get(key) or self._code_info(key)
                if category == event_category:
                    k = len(letters)
                    params: dict[str, float | str] = (
                        {letters[0]: flat[at]} if k == 1 else
                        dict(zip(letters, flat[at:at + k], strict=True)))
                    # Event(base + move_index, lineno, code, params), built field by field
                    event = new(Event)
                    set_index(event, base + move_index)
                    set_line(event, lineno)
                    set_code(event, code)
                    set_params(event, params)
                    append_event(event)
                elif category == IS_UNKNOWN:
                    self._record(code, {}, "", lineno, base + move_index,
                                 Span(buf, start, end), checked=True)
                continue
            text = buf[start:end].decode("utf-8", "replace")
            if "\ufffd" in text:
                self.warnings.append(f"{self.name}:{lineno}: bytes that are not UTF-8 "
                                     "(replaced)")
            if kind == comment:  # the text after ';' of a comment-only line
                feed(text.rstrip(), base + move_index, lineno)
                continue
            stripped = text.lstrip()
            if stripped[:1] == ";":  # comment-only line: straight to the interpreter
                feed(stripped[1:].rstrip(), base + move_index, lineno)
                continue
            text = text.rstrip("\r")
            parsed = parse_line(text, source=self.name, line=lineno)
            self._record(parsed.code, parsed.params, parsed.comment, lineno,
                         self._offset + move_index, text)
        rows.n_other = 0
        rows.n_vals = 0

    def _volumetric_flavor(self, buf: bytes) -> None:
        """E in mm³ from the first line when the header names a volumetric flavor
        (:mod:`flowtwin.gcode.flavors`), with :attr:`ReadOptions.filament_diameter_mm`."""
        flavor = volumetric_flavor(buf)
        if flavor is not None:
            d = self.options.filament_diameter_mm
            self.state[kernel.S_E_FACTOR] = 1.0 / (math.pi * d * d / 4.0)
            self.comments.metadata["volumetric_e"] = flavor

    # -- one chunk -------------------------------------------------------------------------
    def chunk(self, buf: bytes, *, capacity_hint: int = 0) -> MoveTable:
        """Read one piece of the file (ending on a line break) and return its moves.

        With ``accumulate`` the rows go on filling one buffer across chunks (the whole-file
        read: no copies); otherwise each chunk has its own (streaming: bounded memory).
        """
        self.events: list[Event] = []
        arr = np.frombuffer(buf, dtype=np.uint8)
        zero = buf.find(b"\0")
        if zero >= 0:  # a NUL byte: binary data
            line = int(self.state[kernel.S_LINE]) + buf.count(b"\n", 0, zero) + 1
            raise GcodeError("binary data (NUL byte) in G-code", source=self.name, line=line,
                             allowed="text G-code")
        # no counting pass over the bytes: the row buffer is sized from the rows per byte
        # seen so far and grows (from the same estimate) if a chunk holds more
        rows = self.rows if self.accumulate else None
        if rows is None:
            need = int(len(buf) * self.rows_per_byte) + 64
            # comments and other commands are a minority of lines; their buffers grow
            rows = _Rows.make(max(need, capacity_hint), max(256, len(buf) // 1024))
            if self.accumulate:
                self.rows = rows
        rows.n_other = rows.n_vals = 0
        start_n = rows.n
        self._offset = self.n_moves - start_n
        if self.bytes_done == 0:
            self._volumetric_flavor(buf)
        pos = 0
        while True:
            status, pos, rows.n, rows.n_other, rows.n_vals = kernel.scan(
                arr, pos, self.state, rows.moves, rows.n, rows.other, rows.vals, rows.n_other,
                rows.n_vals, self.e_acc)
            if status == kernel.ST_DONE:
                break
            if status == kernel.ST_MOVES_FULL:
                rows.grow_moves(self._more_rows(len(buf) - pos, rows.n - start_n, pos))
            elif status == kernel.ST_OTHER_FULL:
                rows.grow_other()
            elif status == kernel.ST_ERROR:
                raise self._kernel_error(buf, pos)
            else:  # ST_PYTHON: this line is interpreted here, in order
                # lines recorded so far come first
                self._other_lines(buf, rows)
                end = buf.find(b"\n", pos)
                end = len(buf) if end < 0 else end
                line = int(self.state[kernel.S_LINE]) + 1
                text = buf[pos:end].decode("utf-8", "replace").rstrip("\r")
                self._python_line(text, line, rows)
                self.state[kernel.S_LINE] = line
                pos = end + 1
        self._other_lines(buf, rows)
        self.last_byte_newline = buf.endswith(b"\n")
        self.bytes_done += len(buf)
        if len(buf) >= 4096:  # learn the density from chunks long enough to tell
            # (not below one row per 64 bytes: a header of comments says little of the rest)
            self.rows_per_byte = max(1.05 * (rows.n - start_n) / len(buf), 1.0 / 64.0)
        return self._table(rows, start_n)

    def _more_rows(self, bytes_left: int, rows_made: int, bytes_read: int) -> int:
        """Rows to add when the buffer is full: the rest of the chunk (and, for a whole-file
        read, of the file) at the density of this chunk so far, with a margin."""
        density = max(rows_made / max(bytes_read, 1), self.rows_per_byte)
        if self.accumulate:
            bytes_left += max(0, self.total_bytes - self.bytes_done - bytes_left - bytes_read)
        return int(1.1 * density * bytes_left) + 1024

    def _table(self, rows: _Rows, start_n: int = 0) -> MoveTable:
        n = rows.n
        if self.accumulate:
            moves = rows.moves[start_n:n]  # filled in place; the whole read takes the buffer
        else:
            # keep the kernel's buffer when it is mostly full, else copy to release the rest
            moves = (rows.moves[:n] if n >= 0.6 * rows.moves.shape[0]
                     else rows.moves[:n].copy())
        self._assign_columns(moves)
        table = MoveTable(moves=moves, events=self.events,
                          start_xyze=np.zeros(4), source=self.name)
        self.n_moves += n - start_n
        return table

    def _assign_columns(self, moves: np.ndarray) -> None:
        """Feature and layer of every row of the chunk, from the comments read so far."""
        comments = self.comments
        markers = comments.metadata.get("_layer_mode") == "markers" or comments.layer_changes
        if markers:
            comments.metadata["_layer_mode"] = "markers"
            self.layer_z.extend(z for _mi, _line, z in comments.layer_changes)
        self.feature, self.layer, self.max_extrude_z, new_z = fill_columns(
            moves, comments.feature_changes, comments.layer_changes if markers else None,
            base=self.n_moves, feature=self.feature, layer=self.layer,
            max_extrude_z=self.max_extrude_z)
        self.layer_z.extend(new_z)
        comments.feature_changes.clear()
        comments.layer_changes.clear()


# -------------------------------------------------------------------------- public API ---

def iter_move_chunks(source: str | os.PathLike[str] | bytes | BinaryIO, *,
                     options: ReadOptions | None = None,
                     chunk_bytes: int = DEFAULT_CHUNK_BYTES) -> Iterator[MoveTable]:
    """Read G-code in bounded memory, yielding one :class:`MoveTable` per chunk.

    Parameters
    ----------
    source
        A path, ``"-"`` for standard input, the file's bytes, or a binary stream;
        gzip-compressed input and Prusa binary G-code (``.bgcode``) are detected and
        decoded.
    options
        Reading options (arcs, homing position, firmware retraction, strictness).
    chunk_bytes
        Bytes read per chunk; memory stays proportional to it, not to the file.

    Yields
    ------
    MoveTable
        Moves and events of one chunk (move rows, features and layers continue across
        chunks). The last table carries the file's metadata, unknown commands and warnings.
    """
    yield from _drive(source, options or ReadOptions(), chunk_bytes, accumulate=False)[1]


def _drive(source: str | os.PathLike[str] | bytes | BinaryIO, options: ReadOptions,
           chunk_bytes: int, *, accumulate: bool) -> tuple[_Reader, Iterator[MoveTable]]:
    """The reader of ``source`` and the generator of its chunk tables."""
    stream, name = open_source(source)
    reader = _Reader(name, options, accumulate=accumulate)
    hint = 0
    if isinstance(source, str | os.PathLike) and os.fspath(source) != "-":
        try:
            size = os.path.getsize(source)
        except OSError:
            size = -1
        if size >= 0 and not (isinstance(stream, gzip.GzipFile) or _is_bgcode(stream)):
            # ask for no more than the file holds: a read allocates what it is asked for
            chunk_bytes = min(chunk_bytes, size + 1)
        if accumulate and size >= 0 and not _is_bgcode(stream):
            # about one row per 25 bytes of G-code; growth covers the rest
            reader.total_bytes = size
            hint = size // 25

    def tables() -> Iterator[MoveTable]:
        last: MoveTable | None = None
        try:
            for piece in line_chunks(stream, name, chunk_bytes):
                if last is not None:
                    yield last
                last = reader.chunk(piece, capacity_hint=hint)
        finally:
            if isinstance(source, str | os.PathLike) and os.fspath(source) != "-":
                stream.close()
        if last is None:
            last = _empty(reader)
        n_lines = int(reader.state[kernel.S_LINE])
        if not reader.last_byte_newline and n_lines:
            reader.warnings.append(f"{name}:{n_lines}: file does not end with a line break "
                                   "(truncated?)")
        last.metadata = reader.comments.finish()
        last.metadata.pop("_layer_mode", None)
        check_extrusion_axis(last.metadata, name)
        last.features = list(reader.comments.features)
        last.layer_z = list(reader.layer_z)
        last.unknown_commands = dict(sorted(reader.unknown.items(), key=lambda kv: -kv[1]))
        last.warnings = list(reader.warnings)
        last.n_lines = n_lines
        info = getattr(stream, "info", None) if _is_bgcode(stream) else None
        if info is not None:
            last.metadata["bgcode"] = info.as_metadata()
        yield last

    return reader, tables()


def _is_bgcode(stream: object) -> bool:
    """Whether ``stream`` decodes a ``.bgcode`` (its module is imported only for one)."""
    module = sys.modules.get("flowtwin.gcode.bgcode.read")
    return module is not None and isinstance(stream, module.BgcodeText)


def _empty(reader: _Reader) -> MoveTable:
    reader.events = []
    rows = _Rows.make(0, 0)
    if reader.accumulate:
        reader.rows = rows
    return reader._table(rows)


def read_gcode(source: str | os.PathLike[str] | bytes | BinaryIO, *,
               options: ReadOptions | None = None) -> MoveTable:
    """Read a whole G-code file into one :class:`MoveTable`.

    Parameters
    ----------
    source
        A path (plain, gzip or ``.bgcode``), ``"-"`` for standard input, bytes, or a
        binary stream.
    options
        Reading options; defaults to :class:`ReadOptions`.

    Returns
    -------
    MoveTable
        One row per straight segment, events, metadata, unknown commands, warnings.

    Raises
    ------
    GcodeError
        The file cannot be read, or a word or number is malformed (message names the file
        and line).
    """
    options = options or ReadOptions()
    reader, tables = _drive(source, options, DEFAULT_CHUNK_BYTES, accumulate=True)
    chunks = list(tables)
    last = chunks[-1]
    rows = reader.rows
    assert rows is not None
    n = rows.n
    # every chunk was written into one buffer: take it (copy only to release much slack)
    moves = rows.moves[:n] if n >= 0.6 * rows.moves.shape[0] else rows.moves[:n].copy()
    table = MoveTable(moves=moves, events=[e for c in chunks for e in c.events],
                      start_xyze=np.array([*options.start_xyz, 0.0]), features=last.features,
                      layer_z=last.layer_z, metadata=last.metadata,
                      unknown_commands=last.unknown_commands, warnings=last.warnings,
                      source=last.source, n_lines=last.n_lines)
    return table
