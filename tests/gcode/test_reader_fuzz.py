"""Fuzzing the reader: it raises nothing but GcodeError, whatever the bytes."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtwin.errors import GcodeError
from flowtwin.gcode.reader import ReadOptions, read_gcode

REAL_LINES = [
    b"G1 X10.5 Y20.25 E0.0312 F1800", b"G0 X1 Y2", b"G2 X10 Y10 I5 J0 E1", b"G3 X0 Y0 R5",
    b"G92 E0", b"M83", b"M82", b"G91", b"G90", b"T1", b"M221 S95", b"M220 S50", b"G28 X",
    b"M204 P1500 T3000", b"SET_VELOCITY_LIMIT ACCEL=500", b";TYPE:Perimeter", b";LAYER:3",
    b"N12 G1 X1*99", b"G10", b"G11", b"M207 S2 F1800", b"M200 D1.75", b"G20", b"G21",
    b"G4 P100", b"M900 K0.05", b"; estimated printing time (normal mode) = 1h 2m 3s",
]


def _check(data: bytes) -> None:
    try:
        table = read_gcode(data, options=ReadOptions(arc_tolerance_mm=0.05))
    except GcodeError as exc:
        assert str(exc)  # a message, never empty
        return
    moves = table.moves
    for col in ("x", "y", "z", "e", "de", "feed_mm_s"):
        assert np.all(np.isfinite(moves[col])), col


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=400))
def test_random_bytes(data: bytes) -> None:
    _check(data)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.sampled_from(REAL_LINES), st.integers(0, 60),
                          st.binary(max_size=3)), max_size=25))
def test_mutated_real_lines(edits: list[tuple[bytes, int, bytes]]) -> None:
    lines = []
    for line, pos, junk in edits:
        pos = min(pos, len(line))
        lines.append(line[:pos] + junk + line[pos:])
    _check(b"\n".join(lines) + b"\n")
