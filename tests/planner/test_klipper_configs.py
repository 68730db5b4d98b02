"""Every printer Klipper ships a config for loads and plans a small print on its bed.

Input: Klipper's own ``config/printer-*.cfg`` and ``config/example-*.cfg`` (repository
Klipper3d/klipper, commit 84104bb; ``tests/data/klipper-config/PROVENANCE.md``), read as a
user would hand them to ``flowtwin plan --klipper-config``: includes, macros, pins and the
sections flowtwin does not use are ignored. For each one with a ``[printer]`` section a
30 × 20 mm print from flowtwin's generator is placed at the centre of the axis range the
kinematics reports and planned; every move must stay inside that range.
"""

from __future__ import annotations

import re
import tarfile
from pathlib import Path

import numpy as np
import pytest

from flowtwin.errors import ProfileError
from flowtwin.gcode.generator import PrintSpec, generate_print
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import KINEMATICS, klipper_read_options, load_printer_cfg

DATA = Path(__file__).resolve().parents[1] / "data" / "klipper-config"
TARBALL = DATA / "klipper-config-84104bb.tar.gz"
COMMIT = "84104bbbd7625d28b4eaaad83f4562972460ecd9"


def _names() -> list[str]:
    with tarfile.open(TARBALL) as tar:
        return sorted(m.name.split("/")[-1] for m in tar.getmembers() if m.isfile())


NAMES = _names()


@pytest.fixture(scope="module")
def config_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("klipper-config")
    with tarfile.open(TARBALL) as tar:
        if hasattr(tarfile, "data_filter"):      # Python >= 3.11.4
            tar.extractall(out, filter="data")
        else:
            assert all(m.isfile() or m.isdir() for m in tar.getmembers())
            assert not any(m.name.startswith("/") or ".." in m.name for m in tar.getmembers())
            tar.extractall(out)
    return out / "config"


def test_the_folder_and_its_source_are_recorded():
    provenance = (DATA / "PROVENANCE.md").read_text(encoding="utf-8")
    assert COMMIT in provenance and "github.com/Klipper3d/klipper" in provenance
    assert "not part of the flowtwin package" in provenance
    assert "GNU GENERAL PUBLIC LICENSE" in (DATA / "COPYING").read_text(encoding="utf-8")
    assert len(NAMES) == 120
    assert all(n.startswith(("printer-", "example-")) and n.endswith(".cfg") for n in NAMES)


def _fits(lo: float, hi: float, want: float) -> float:
    return min(want, 0.6 * (hi - lo)) if np.isfinite(hi - lo) else want


@pytest.mark.parametrize("name", NAMES)
def test_config_loads_and_plans_a_print_on_its_bed(config_dir, tmp_path, name):
    path = config_dir / name
    if "[printer]" not in path.read_text(encoding="utf-8"):
        with pytest.raises(ProfileError, match=r"no \[printer\] section"):
            load_printer_cfg(path)
        return
    settings = load_printer_cfg(path)
    assert settings.kinematics in KINEMATICS
    kin = settings.kinematics_model
    lo, hi = np.array(kin.axes_min), np.array(kin.axes_max)
    centre = np.where(np.isfinite(lo + hi), (lo + hi) / 2.0, 0.0)
    if settings.kinematics in ("delta", "rotary_delta"):
        reach = float(hi[0])          # a round bed: keep the print well inside it
        size = (min(30.0, 0.5 * reach), min(20.0, 0.35 * reach))
    else:
        size = (_fits(lo[0], hi[0], 30.0), _fits(lo[1], hi[1], 20.0))
    ex = settings.extruders[0] if settings.extruders else None
    spec = PrintSpec(size_x_mm=size[0], size_y_mm=size[1],
                     center_xy_mm=(float(centre[0]), float(centre[1])), layers=3,
                     use_arcs=False, nozzle_diameter_mm=ex.nozzle_diameter if ex else 0.4,
                     filament_diameter_mm=ex.filament_diameter if ex else 1.75,
                     line_width_mm=1.1 * (ex.nozzle_diameter if ex else 0.4),
                     layer_height_mm=0.5 * (ex.nozzle_diameter if ex else 0.4),
                     pillar_radius_mm=min(4.0, size[1] / 6))
    text = "\n".join(generate_print(spec)) + "\n"
    if lo[2] > 0.0:      # a bed above Z 0 (position_min > 0): lift the whole print
        text = re.sub(r"Z(\d+\.\d+)", lambda m: f"Z{float(m.group(1)) + lo[2]:.3f}", text)
    gcode = tmp_path / "small.gcode"
    gcode.write_text(text, encoding="utf-8")
    table = read_gcode(gcode, options=klipper_read_options(settings))
    timeline = plan_klipper(table, settings)
    assert timeline.total_time_s > 10.0
    moves = table.moves
    for axis, col in enumerate("xyz"):
        assert np.all(moves[col] >= lo[axis] - 1e-9) and np.all(moves[col] <= hi[axis] + 1e-9)
