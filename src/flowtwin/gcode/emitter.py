"""Writing G-code: the one emitter behind every file flowtwin writes from scratch.

A :class:`GcodeEmitter` turns moves and commands into lines and keeps what a firmware
keeps while it reads them: the toolhead position, the E axis (relative ``M83`` or absolute
``M82``; ``G92`` resets it), the modal feed rate ``F`` (mm/min), the net filament asked for
and the number of E words written. Numbers are written with one :class:`NumberFormat` per
word (``X``/``Y``/``Z``, ``E``, ``F``, arc offsets ``I``/``J``), chosen once per file, so a
file never mixes two spellings of the same quantity.

The built-in example print (:mod:`flowtwin.gcode.generator`), the calibration patterns,
the print-job test part of [003] and the twin's short advance test prints are written with
it. A rewrite of an existing file keeps the file's own bytes instead
(:mod:`flowtwin.gcode.writer`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

from flowtwin.errors import GcodeError

__all__ = ["GcodeEmitter", "NumberFormat", "Retraction", "WordFormats", "format_number"]


def format_number(value: float, decimals: int = 5) -> str:
    """``value`` with at most ``decimals`` decimals, trailing zeros removed (``0.05``, ``0``).

    Raises
    ------
    GcodeError
        ``value`` is not finite (G-code has no spelling for it).
    """
    if not math.isfinite(value):
        raise GcodeError("a G-code number must be finite", value=value,
                         allowed="a finite number")
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


@dataclass(frozen=True, slots=True)
class NumberFormat:
    """How one G-code word writes its number.

    Attributes
    ----------
    decimals
        Digits after the decimal point.
    trim
        Remove trailing zeros (``1.5`` rather than ``1.500``; ``0`` for zero).
    """

    decimals: int
    trim: bool = False

    def __call__(self, value: float) -> str:
        """``value`` in this format."""
        if self.trim:
            return format_number(value, self.decimals)
        if not math.isfinite(value):
            raise GcodeError("a G-code number must be finite", value=value,
                             allowed="a finite number")
        return f"{value:.{self.decimals}f}"


@dataclass(frozen=True, slots=True)
class WordFormats:
    """The number format of each word of a file (defaults: slicer-like fixed decimals).

    Attributes
    ----------
    xyz
        Positions ``X``, ``Y``, ``Z``, mm.
    e
        Extrusion ``E``, mm of filament.
    f
        Feed rate ``F``, mm/min.
    ij
        Arc centre offsets ``I``, ``J``, mm.
    """

    xyz: NumberFormat = NumberFormat(3)
    e: NumberFormat = NumberFormat(5)
    f: NumberFormat = NumberFormat(0)
    ij: NumberFormat = NumberFormat(3)


@dataclass(frozen=True, slots=True)
class Retraction:
    """How a travel retracts: pull the filament back, lift, travel, lower, push it back.

    Attributes
    ----------
    length_mm
        Filament pulled back (and pushed back after the travel), mm.
    f_mm_min
        Feed rate of the retract and unretract moves, mm/min.
    z_hop_mm
        Lift during the travel, mm; 0: none.
    z_hop_f_mm_min
        Feed rate of the lift and the lowering, mm/min.
    """

    length_mm: float
    f_mm_min: float
    z_hop_mm: float = 0.0
    z_hop_f_mm_min: float = 600.0


class GcodeEmitter:
    """Writes G-code lines and keeps the state a firmware keeps while reading them.

    Parameters
    ----------
    formats
        Number format of each word.
    repeat_f
        Write ``F`` on every move (``True``), or only when it changes (modal ``F``).

    Attributes
    ----------
    x, y, z
        Toolhead position after the last line, mm (as given to the emitter).
    e_mm
        Position of the E axis as the firmware counts it (``G92`` resets it), mm.
    relative_e
        Whether ``E`` words are increments (``M83``) or positions (``M82``).
    f_mm_min
        Feed rate in force (``None`` before the first ``F``), mm/min.
    filament_mm
        Net filament asked for since the start (every ``E`` increment, ``G92`` aside), mm.
    e_words
        Number of ``E`` words written.
    n_lines
        Number of lines written (the 1-based number of the last one).
    """

    def __init__(self, formats: WordFormats | None = None, *, repeat_f: bool = True) -> None:
        self.formats = formats or WordFormats()
        self.repeat_f = repeat_f
        self.x = 0.0
        self.y = 0.0
        self.z = 0.0
        self.e_mm = 0.0
        self.relative_e = True
        self.f_mm_min: float | None = None
        self.filament_mm = 0.0
        self.e_words = 0
        self.n_lines = 0
        self._pending: list[str] = []

    # -- output ----------------------------------------------------------------------
    @property
    def lines(self) -> list[str]:
        """Lines written and not yet taken by :meth:`drain`."""
        return self._pending

    def drain(self) -> Iterator[str]:
        """Yield the lines written since the last drain (for streaming output)."""
        lines, self._pending = self._pending, []
        yield from lines

    def text(self) -> str:
        """The pending lines as one text, a line break after each."""
        return "".join(line + "\n" for line in self._pending)

    def line(self, text: str) -> int:
        """Write ``text`` as it is (one line, no line break); return its 1-based number."""
        if "\n" in text or "\r" in text:
            raise GcodeError("one line at a time", value=text, allowed="text without "
                                                                       "line breaks")
        self._pending.append(text)
        self.n_lines += 1
        return self.n_lines

    def comment(self, text: str) -> int:
        """Write ``; text``."""
        return self.line(f"; {text}")

    def marker(self, name: str, value: str | None = None) -> int:
        """Write a slicer marker the reader picks up: ``;NAME`` or ``;NAME:value``
        (``;LAYER_CHANGE``, ``;Z:0.200``, ``;TYPE:External perimeter``)."""
        return self.line(f";{name}" if value is None else f";{name}:{value}")

    def command(self, code: str, *, comment: str | None = None,
                **params: float | int | str) -> int:
        """Write ``code`` with parameters in the order given and an optional comment.

        Integers are written as they are, floats with at most five decimals (trailing
        zeros removed), strings verbatim (``command("M104", S=215)`` → ``M104 S215``).
        """
        words = [code]
        for name, value in params.items():
            if isinstance(value, str):
                words.append(f"{name}{value}")
            elif isinstance(value, bool | int):
                words.append(f"{name}{int(value)}")
            else:
                words.append(f"{name}{format_number(value)}")
        text = " ".join(words)
        return self.line(text if comment is None else f"{text} ; {comment}")

    # -- modes and machine state -----------------------------------------------------
    def begin(self, *, relative_e: bool = True) -> None:
        """Millimetres, absolute XYZ, relative (or absolute) E, each with its comment."""
        self.line("G21 ; millimetres")
        self.line("G90 ; absolute XYZ")
        self.set_relative_e(relative_e)

    def set_relative_e(self, relative: bool) -> int:
        """``M83 ; relative E`` or ``M82 ; absolute E``."""
        self.relative_e = relative
        return self.line("M83 ; relative E" if relative else "M82 ; absolute E")

    def reset_e(self, value_mm: float = 0.0) -> int:
        """``G92 E<value>``: the E axis counts from ``value_mm`` on."""
        self.e_mm = value_mm
        return self.line(f"G92 E{format_number(value_mm)}")

    def home(self) -> int:
        """``G28 ; home``; the writers place their parts with home at the origin."""
        self.x = self.y = self.z = 0.0
        return self.line("G28 ; home")

    def heat_nozzle(self, temp_c: float, *, wait: bool = False, either_way: bool = False,
                    comment: str | None = None) -> int:
        """``M104 S`` (set), ``M109 S`` (set and wait to heat) or ``M109 R`` (set and wait
        to heat or cool), °C (written as :meth:`command` writes numbers: pass an ``int``
        for whole degrees)."""
        code = "M109" if wait or either_way else "M104"
        word = "R" if either_way else "S"
        return self.command(code, comment=comment, **{word: temp_c})

    def heat_bed(self, temp_c: float, *, wait: bool = False) -> int:
        """``M140 S`` or ``M190 S`` (wait), °C."""
        return self.command("M190" if wait else "M140", S=temp_c)

    def fan(self, percent: float) -> int:
        """``M106 S<0-255>``, or ``M107`` at 0 %."""
        if percent > 0:
            return self.command("M106", S=round(255 * percent / 100.0))
        return self.line("M107")

    # -- motion ----------------------------------------------------------------------
    def move(self, *, x: float | None = None, y: float | None = None, z: float | None = None,
             e_mm: float | None = None, f_mm_min: float | None = None,
             code: str = "G1") -> int:
        """A straight move: ``G1 X Y Z E F`` with the words given.

        Parameters
        ----------
        x, y, z
            Target position, mm (absolute XYZ).
        e_mm
            Filament to push (negative: pull back), mm: written as an increment in
            relative mode, as the new E position in absolute mode.
        f_mm_min
            Feed rate, mm/min (left out when unchanged and ``repeat_f`` is off).
        code
            ``"G1"`` or ``"G0"``.

        Returns
        -------
        int
            The 1-based number of the line.
        """
        fmt = self.formats
        words = [code]
        for letter, value in (("X", x), ("Y", y), ("Z", z)):
            if value is not None:
                words.append(letter + fmt.xyz(value))
        if e_mm is not None:
            words.append("E" + self._e_word(e_mm))
        words.extend(self._f_word(f_mm_min))
        if x is not None:
            self.x = x
        if y is not None:
            self.y = y
        if z is not None:
            self.z = z
        return self.line(" ".join(words))

    def arc(self, *, x: float, y: float, i: float, j: float, e_mm: float | None = None,
            f_mm_min: float | None = None, clockwise: bool = False) -> int:
        """An XY arc around ``(x0 + i, y0 + j)`` to ``(x, y)``: ``G2`` (clockwise) or ``G3``."""
        fmt = self.formats
        words = ["G2" if clockwise else "G3", "X" + fmt.xyz(x), "Y" + fmt.xyz(y),
                 "I" + fmt.ij(i), "J" + fmt.ij(j)]
        if e_mm is not None:
            words.append("E" + self._e_word(e_mm))
        words.extend(self._f_word(f_mm_min))
        self.x, self.y = x, y
        return self.line(" ".join(words))

    def travel(self, x: float, y: float, f_mm_min: float,
               retraction: Retraction | None = None) -> None:
        """Travel to ``(x, y)``; with ``retraction``: retract and lift first, lower and
        unretract after. Nothing is written when already there."""
        if math.hypot(x - self.x, y - self.y) < 1e-9:
            return
        r = retraction
        if r is not None:
            self.move(e_mm=-r.length_mm, f_mm_min=r.f_mm_min)
            if r.z_hop_mm:
                z = self.z
                self.move(z=z + r.z_hop_mm, f_mm_min=r.z_hop_f_mm_min)
                self.z = z  # the layer's height; the lift is undone after the travel
        self.move(x=x, y=y, f_mm_min=f_mm_min)
        if r is not None:
            if r.z_hop_mm:
                self.move(z=self.z, f_mm_min=r.z_hop_f_mm_min)
            self.move(e_mm=r.length_mm, f_mm_min=r.f_mm_min)

    # -- words -----------------------------------------------------------------------
    def _e_word(self, e_mm: float) -> str:
        self.e_words += 1
        self.filament_mm += e_mm
        self.e_mm += e_mm
        return self.formats.e(e_mm if self.relative_e else self.e_mm)

    def _f_word(self, f_mm_min: float | None) -> list[str]:
        if f_mm_min is None or (not self.repeat_f and f_mm_min == self.f_mm_min):
            return []
        self.f_mm_min = f_mm_min
        return ["F" + self.formats.f(f_mm_min)]
