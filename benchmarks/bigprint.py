"""Large real-slicer prints for the end-to-end benchmarks (generated, never committed).

* :func:`big_print` — a 2.82 M-line print (15.5 h by PrusaSlicer's estimate): an OpenSCAD
  dome (a hemisphere on a drum, twelve vertical bores) sliced by Debian's ``prusa-slicer``
  at 0.1 mm layers, gyroid infill. Needs ``apt-get install -y prusa-slicer openscad``;
  takes a few minutes once and is cached in ``bench-out/``.
* :func:`gigabyte_print` — a G-code file of about 1 GB for the bounded-memory check
  (issue #21.3): the big print's moves repeated in place, written once into ``bench-out/``.

Usage: ``python -m benchmarks.bigprint [big|gigabyte]`` prints the path (generating it).
"""

from __future__ import annotations

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


def gigabyte_print(out_dir: Path = OUT, size_bytes: int = 1_000_000_000) -> Path:
    """A G-code file of about ``size_bytes``: the big print's body (from its first layer to
    its end G-code) printed again and again in the same place, ``G92 E0`` before each copy
    (a farm job repeating one part; every copy within any printer's build volume)."""
    path = out_dir / f"dome-x{size_bytes // 1_000_000}MB.gcode"
    if path.exists():
        return path
    src = big_print(out_dir).read_bytes()
    start = src.index(b";LAYER_CHANGE")
    end = src.index(b"\nM107", src.rindex(b";LAYER_CHANGE")) + 1
    head, body = src[:start], b"G92 E0\n" + src[start:end]
    tmp = path.with_suffix(".tmp.gcode")
    with open(tmp, "wb") as f:
        f.write(head)
        while f.tell() < size_bytes:
            f.write(body)
        f.write(src[end:])
    tmp.replace(path)
    return path


if __name__ == "__main__":
    which = sys.argv[1] if len(sys.argv) > 1 else "big"
    print(gigabyte_print() if which == "gigabyte" else big_print())
