"""Large real-slicer prints for the end-to-end benchmarks (generated, never committed).

* :func:`big_print` — a 2.82 M-line print (15.5 h by PrusaSlicer's estimate): an OpenSCAD
  dome (a hemisphere on a drum, twelve vertical bores) sliced by Debian's ``prusa-slicer``
  at 0.1 mm layers, gyroid infill. Needs ``apt-get install -y prusa-slicer openscad``;
  takes a few minutes once and is cached in ``bench-out/``.
* :func:`gigabyte_print` — a G-code file of about 1 GB for the bounded-memory check
  (issue #21.3): the big print's moves repeated, each copy lifted above the previous one
  (so the file is one real, ever taller print), written once into ``bench-out/``.

Usage: ``python -m benchmarks.bigprint [big|gigabyte]`` prints the path (generating it).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench-out"

#: The model: a 110 mm hemisphere on an 80 mm drum with twelve 12 mm bores.
DOME_SCAD = """$fn=200;
difference(){ union(){ sphere(r=55); translate([0,0,-55]) cylinder(r=40,h=20); }
  for (a=[0:30:330]) rotate([0,0,a]) translate([35,0,0]) cylinder(r=6,h=200,center=true);
  translate([0,0,-100]) cube(200,center=true); }
"""

#: PrusaSlicer options (its defaults otherwise: RepRap/Marlin flavour, 2 perimeters).
SLICER_ARGS = ("--layer-height", "0.1", "--first-layer-height", "0.2", "--center", "110,110",
               "--fill-pattern", "gyroid", "--fill-density", "15%")


def big_print(out_dir: Path = OUT) -> Path:
    """The 2.82 M-line PrusaSlicer print (generated once, then cached)."""
    path = out_dir / "dome-0.1mm.gcode"
    if path.exists():
        return path
    for tool in ("openscad", "prusa-slicer"):
        if shutil.which(tool) is None:
            raise SystemExit(f"{tool} not found: apt-get install -y prusa-slicer openscad")
    out_dir.mkdir(parents=True, exist_ok=True)
    scad = out_dir / "dome.scad"
    stl = out_dir / "dome.stl"
    scad.write_text(DOME_SCAD)
    if not stl.exists():
        subprocess.run(["openscad", "-o", str(stl), str(scad)], check=True,
                       capture_output=True)
    tmp = path.with_suffix(".tmp.gcode")
    subprocess.run(["prusa-slicer", "--export-gcode", *SLICER_ARGS, "-o", str(tmp), str(stl)],
                   check=True, capture_output=True)
    tmp.replace(path)
    return path


_Z = re.compile(rb"Z(-?[0-9.]+)")


def gigabyte_print(out_dir: Path = OUT, size_bytes: int = 1_000_000_000) -> Path:
    """A G-code file of about ``size_bytes``: the big print's body repeated, each copy
    lifted by the height of the previous ones (absolute Z rewritten), ``G92 E0`` between
    copies so absolute E restarts."""
    path = out_dir / f"dome-x{size_bytes // 1_000_000}MB.gcode"
    if path.exists():
        return path
    src = big_print(out_dir).read_bytes()
    lines = src.split(b"\n")
    # the print's body: from the first layer change to the end G-code
    start = next(i for i, ln in enumerate(lines) if ln.startswith(b";LAYER_CHANGE"))
    end = max(i for i, ln in enumerate(lines) if ln.startswith(b";LAYER_CHANGE"))
    end = next((i for i in range(end, len(lines)) if lines[i].startswith(b"M107")), end)
    head, body = b"\n".join(lines[:start]) + b"\n", lines[start:end]
    top = max(float(m.group(1)) for ln in body if ln.startswith(b"G1") and b"Z" in ln
              for m in [_Z.search(ln.split(b";")[0])] if m)
    tmp = path.with_suffix(".tmp.gcode")
    written = 0
    with open(tmp, "wb") as f:
        f.write(head)
        copy = 0
        while written < size_bytes:
            lift = copy * top
            f.write(b"G92 E0\n")
            for ln in body:
                if lift and ln.startswith(b"G1") and b"Z" in ln:
                    code = ln.split(b";")[0]
                    m = _Z.search(code)
                    if m:
                        ln = code[:m.start()] + b"Z%.3f" % (float(m.group(1)) + lift) \
                            + code[m.end():]
                f.write(ln + b"\n")
            written = f.tell()
            copy += 1
    tmp.replace(path)
    return path


if __name__ == "__main__":
    which = sys.argv[1] if len(sys.argv) > 1 else "big"
    print(gigabyte_print() if which == "gigabyte" else big_print())
