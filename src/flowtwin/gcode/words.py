"""Splitting one G-code line into a command and its parameters (the slow, exact path).

The numba kernel handles the frequent commands; every other line comes here. The rules
follow what firmware does: everything from the first ``;`` is a comment; an ``N<n>`` line
number and a ``*<sum>`` checksum are stripped (the checksum is verified by the kernel);
letters are upper-cased; a *classic* command is a letter and a number (``G1``, ``M620.1``,
``T1000``) followed by letter/number words (``X10 Y-2.5``, ``G1Z200`` without spaces too);
an *extended* command (``SET_VELOCITY_LIMIT ACCEL=500``) has ``NAME=value`` parameters.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from flowtwin.errors import GcodeError

__all__ = ["ParsedLine", "parse_line"]

_CLASSIC = re.compile(r"([A-Z])([0-9]+(?:\.[0-9]+)?)")
_WORD = re.compile(r"([A-Z])\s*([^A-Z\s]*)")
#: possessive quantifiers: the words' whitespace can be split between them in many ways, and a
#: line that does not match (a 4.6 kB line of CR-separated commands) made the backtracking
#: search exponential; the greedy split is the only one that matters
_ALL_WORDS = re.compile(r"(?:\s*+[A-Z]\s*+[^A-Z\s]*+)*+\s*+")
_EXTENDED = re.compile(r"[A-Z_][A-Z0-9_]*")
_NLINE = re.compile(r"N\s*[0-9]+\s*")

#: Largest magnitude accepted for a numeric parameter.
MAX_ABS_VALUE = 1.0e9


@dataclass(frozen=True, slots=True)
class ParsedLine:
    """One line split into command, parameters and comment.

    Attributes
    ----------
    code
        Upper-case command (``"G1"``, ``"M620.1"``, ``"SET_VELOCITY_LIMIT"``), or ``""``
        for a comment-only / blank line.
    params
        Parameter name → float, or the raw string when it is not a number (an empty
        string for a bare letter such as ``M221 S``).
    comment
        Text after the first ``;`` (without the ``;``), or ``""``.
    """

    code: str
    params: dict[str, float | str]
    comment: str


def _number(text: str) -> float | None:
    """A finite decimal number (no exponent, no ``_``), or ``None``."""
    if "_" in text:
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    if not math.isfinite(value) or abs(value) > MAX_ABS_VALUE:
        return None
    return value


def parse_line(text: str, *, source: str = "<input>", line: int | None = None,
               numeric: frozenset[str] | None = None) -> ParsedLine:
    """Split a G-code line.

    Parameters
    ----------
    text
        The line without its newline.
    source, line
        Used in error messages.
    numeric
        Parameter letters that must be numbers for this command (``None``: none are
        required; non-numbers are then kept as strings).

    Raises
    ------
    GcodeError
        A parameter listed in ``numeric`` is not a valid finite number, or a classic
        command has junk between its words.
    """
    body, sep, comment = text.partition(";")
    star = body.find("*")
    if star >= 0:
        body = body[:star]
    body = body.strip()
    if not body:
        return ParsedLine("", {}, comment.strip() if sep else "")
    upper = body.upper()
    m = _NLINE.match(upper)
    if m:
        upper = upper[m.end():]
        body = body[m.end():]
        if not upper:
            return ParsedLine("", {}, comment.strip() if sep else "")
    classic = _CLASSIC.match(upper)
    params: dict[str, float | str] = {}
    if classic and (classic.end() == len(upper) or upper[classic.end()].isspace()
                    or upper[classic.end()].isalpha()):
        code = classic.group(1) + classic.group(2)
        rest = upper[classic.end():]
        # Klipper: a word is a letter followed by everything up to the next letter/space
        if _ALL_WORDS.fullmatch(rest) is None:
            if numeric is None:
                # an unknown vendor syntax (``M1002 set_gcode_claim_speed_level : 5``):
                # keep the text, the command has no effect on the twin
                params["_"] = rest.strip()
                return ParsedLine(code, params, comment.strip() if sep else "")
            bad = _ALL_WORDS.match(rest)
            at = bad.end() if bad else 0
            raise GcodeError(f"unexpected character {rest[at:at + 1]!r} in {code} parameters",
                             source=source, line=line, value=text.strip(),
                             allowed="letter/number words such as X10.5")
        for letter, raw in _WORD.findall(rest):
            value = _number(raw) if raw else None
            if value is None:
                if numeric is not None and letter in numeric:
                    raise GcodeError(f"{code} parameter {letter} is not a number",
                                     source=source, line=line, field=letter, value=raw,
                                     allowed=f"finite decimal number, |x| <= {MAX_ABS_VALUE:g}")
                params[letter] = raw
            else:
                params[letter] = value
        return ParsedLine(code, params, comment.strip() if sep else "")
    em = _EXTENDED.match(upper)
    if em is None:
        raise GcodeError("line does not start with a command", source=source, line=line,
                         value=text.strip(), allowed="G/M/T codes or NAME=value commands")
    code = em.group(0)
    for token in body[em.end():].split():
        key, eq, raw = token.partition("=")
        if not eq:
            params[key.upper()] = ""
            continue
        value = _number(raw)
        params[key.upper()] = raw if value is None else value
    return ParsedLine(code, params, comment.strip() if sep else "")
