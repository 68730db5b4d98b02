"""G-code documents built from real slicer lines, odd-but-valid commands and mutations."""

from __future__ import annotations

import random
from pathlib import Path

from fuzz.mutate import BOUNDARY_NUMBERS, mutate_line

#: commands slicers rarely write, in odd but mostly valid forms (the reader refuses some)
ODD_COMMANDS = (
    "G90", "G91", "M82", "M83", "G92 E0", "G92 X0 Y0 Z0 E0", "G92", "G28", "G28 X", "G21",
    "G20", "G4 P0", "G4 S1", "G4", "M400", "M204 S500", "M204 P300", "M204 T300",
    "M204 P1000 T200", "M204 R100", "M205 X8 Y8 E4", "M205 J0.02", "M203 X100 E0",
    "M201 X0 Y0", "M220 S10", "M220 S1000", "M221 S0", "M221", "M221 S", "M900 K0.05",
    "M900 K-1", "M572 D0 S0.05", "M572 S0.05", "M207 S1 F1800", "G10", "G11", "G10 P0 S200",
    "M104 S215", "M109 S215", "M104 S-10", "M104 S9999", "M106 S255", "M107", "T0", "T1",
    "T255", "T1000", "T-1", "M82 ; absolute", "G1 F0", "G1 F-100", "G1 E-5 F2400",
    "G1 E1000 F6000", "G0 X0 Y0", "G1 X0 Y0 Z0 E0 F1", "G2 X10 Y0 I5 J0 E1", "G3 X0 Y0 I5 J0",
    "G2 X10 Y10 R5 E1", "G2 X10 Y10 R-5", "G2 X0 Y0 I0 J0 E1", "G3 X10 Y10 I1e-9 J0",
    "G2 X1 Y1 I100000 J0 E1", "G2 P3 X0 Y0 I5 J0 E1", "G2 X10 Y0 Z5 I5 J0 E1",
    "SET_VELOCITY_LIMIT VELOCITY=100 ACCEL=1000", "SET_VELOCITY_LIMIT ACCEL=0",
    "SET_VELOCITY_LIMIT SQUARE_CORNER_VELOCITY=-1", "SET_PRESSURE_ADVANCE ADVANCE=0.04",
    "SET_PRESSURE_ADVANCE ADVANCE=-1 SMOOTH_TIME=0", "SET_PRESSURE_ADVANCE SMOOTH_TIME=0.2",
    "EXCLUDE_OBJECT_START NAME=a", "M73 P50 R10", "M73 Q50 S10", "M117 hello", "M118 E1",
    "M486 S1", "G29", "G80", "M592 A0.1 B0 C0", "M600", "M0", "M1", "M84", "N10 G1 X1*35",
    ";LAYER_CHANGE", ";Z:0.2", ";HEIGHT:0.2", ";TYPE:External perimeter", ";TYPE:",
    ";LAYER:0", ";LAYER:-5", "; layer 1, Z = 0.2", ";WIDTH:0.45", "; total estimated time:",
    "; estimated printing time (normal mode) = 1d 2h 3m 4s", "; filament used [mm] = 1,2,3",
    "; filament_diameter = 1.75", "; nozzle_diameter = 0.4,0.6", "; layer_height = 0",
    "; max_print_speed = 1e9", "; machine_max_acceleration_x = 0,0", "(paren comment)",
    "", " ", "\t", ";", "%",
)


class LinePool:
    """Real lines from the reference corpus (a sample of distinct lines)."""

    def __init__(self, corpus: Path, rng: random.Random, per_file: int = 4000) -> None:
        lines: list[bytes] = []
        for path in sorted(corpus.glob("*.gcode")):
            file_lines = path.read_bytes().split(b"\n")
            step = max(1, len(file_lines) // per_file)
            start = rng.randrange(step)
            lines.extend(file_lines[start::step])
        self.lines = sorted(set(lines))
        self.runs = [path.read_bytes().split(b"\n") for path in sorted(corpus.glob("*.gcode"))]

    def real_run(self, rng: random.Random, n: int) -> list[bytes]:
        """``n`` consecutive lines of a real file (a slice with its modal state)."""
        lines = rng.choice(self.runs)
        start = rng.randrange(max(1, len(lines) - n))
        return lines[start:start + n]


def _move(rng: random.Random, hostile: bool) -> bytes:
    words = [rng.choice(("G1", "G0", "G1", "G1"))]
    for axis in "XYZEF":
        if rng.random() < 0.6:
            if hostile and rng.random() < 0.05:
                value = rng.choice(BOUNDARY_NUMBERS)
            elif axis == "F":
                value = f"{rng.uniform(1, 20000):.0f}"
            elif axis == "E":
                value = f"{rng.uniform(-2, 5):.5f}"
            elif axis == "Z":
                value = f"{rng.uniform(0, 5):.3f}"
            else:
                value = f"{rng.uniform(-50, 250):.3f}"
            words.append(axis + value)
    return " ".join(words).encode()


def document(rng: random.Random, pool: LinePool) -> bytes:
    """One G-code document (usually 0-400 lines; rarely tens of thousands).

    Half the documents are *benign* (real slices and odd commands, no edits: they should
    mostly read and go on through the pipelines), half *hostile* (edited lines, boundary
    numbers).
    """
    hostile = rng.random() < 0.5
    kind = rng.random()
    if kind < 0.002:
        return b""
    if kind < 0.003:  # huge: a real file slice repeated
        body = pool.real_run(rng, 2000) * rng.randrange(5, 25)
    elif kind < 0.4:  # a real slice
        body = pool.real_run(rng, rng.randrange(1, 400))
    else:  # a mix of real lines, odd commands and random moves
        body = []
        for _ in range(rng.randrange(1, 200)):
            r = rng.random()
            if r < 0.4:
                body.append(rng.choice(pool.lines))
            elif r < 0.5:
                body.append(rng.choice(ODD_COMMANDS).encode())
            else:
                body.append(_move(rng, hostile))
    if hostile and body:
        for _ in range(rng.randrange(1, 4)):
            i = rng.randrange(len(body))
            body[i] = mutate_line(rng, body[i])
    eol = b"\r\n" if rng.random() < 0.05 else b"\n"
    text = eol.join(body)
    if rng.random() < 0.9:
        text += eol
    if rng.random() < 0.01:
        text = text.replace(b"\n", b"\r")
    return text
