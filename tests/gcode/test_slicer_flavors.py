"""Slicer flavors that change what E means: CuraEngine's volumetric flavors read in mm³
from the header on (``;FLAVOR:UltiGCode``, ``;FLAVOR:Marlin(Volumetric)``), the placeholders
of its header are not estimates, and an extruder on another axis (PrusaSlicer's ``mach3``)
is refused, not read as a print that extrudes nothing.

The real files (``tests/data/cura_flavors``, PROVENANCE.md there) are one model sliced by
Debian's CuraEngine 4.13 twice, with identical settings but for the flavor: UltiGCode
(volumetric E) and Griffin (linear E). Read right, they extrude the same filament.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import ReadOptions, iter_move_chunks, read_gcode

DATA = Path(__file__).resolve().parents[1] / "data" / "slicer_flavors"
ULTI = DATA / "curaengine_4.13_ultigcode.gcode.gz"
GRIFFIN = DATA / "curaengine_4.13_griffin.gcode.gz"


def _area(d_mm: float) -> float:
    return math.pi * d_mm * d_mm / 4.0


@pytest.mark.parametrize("flavor", ["UltiGCode", "Marlin(Volumetric)"])
@pytest.mark.parametrize("diameter", [1.75, 2.85])
def test_a_volumetric_header_reads_e_as_mm3(flavor: str, diameter: float) -> None:
    volume = 7.5  # mm³ in the move's E
    text = f";FLAVOR:{flavor}\n;TIME:100\nG90\nM82\nG1 X10 Y0 E{volume}\n"
    table = read_gcode(text.encode(), options=ReadOptions(filament_diameter_mm=diameter))
    assert table.metadata["volumetric_e"] == flavor
    assert float(table.moves["de"][-1]) == pytest.approx(volume / _area(diameter), rel=1e-12)


@pytest.mark.parametrize("header", [";FLAVOR:Marlin", ";FLAVOR:Griffin",
                                    ";FLAVOR:RepRap (Marlin/Sprinter)",
                                    "; FLAVOR:UltiGCode is mentioned in a comment"])
def test_linear_flavors_and_mentions_stay_linear(header: str) -> None:
    table = read_gcode(f"{header}\nG1 X10 E2.0\n".encode())
    assert "volumetric_e" not in table.metadata
    assert float(table.moves["de"][-1]) == 2.0


def test_the_header_counts_only_at_the_start_of_the_file() -> None:
    filler = "".join(f"; filler line {i}\n" for i in range(400))  # > 4 kB before it
    table = read_gcode((filler + ";FLAVOR:UltiGCode\nG1 X10 E2.0\n").encode())
    assert "volumetric_e" not in table.metadata
    assert float(table.moves["de"][-1]) == 2.0


def _per_layer_filament(path: Path) -> np.ndarray:
    table = read_gcode(path)
    mv = table.moves
    printing = ((mv["kind"] & MoveKind.EXTRUDE) != 0) & ((mv["kind"] & MoveKind.XY) != 0)
    layers = mv["layer"][printing]
    return np.bincount(layers[layers >= 0], weights=mv["de"][printing][layers >= 0])


def test_real_ultigcode_extrudes_the_filament_of_the_same_print_in_linear_e() -> None:
    ulti, griffin = _per_layer_filament(ULTI), _per_layer_filament(GRIFFIN)
    assert ulti.size == griffin.size > 10
    # the same paths; E written to 5 decimals in mm³ against mm: equal to rounding
    np.testing.assert_allclose(ulti, griffin, rtol=2e-4)


def test_streamed_read_applies_the_header_too() -> None:
    whole = read_gcode(ULTI)
    streamed = np.concatenate([t.moves["de"] for t in iter_move_chunks(ULTI,
                                                                       chunk_bytes=8192)])
    np.testing.assert_array_equal(streamed, whole.moves["de"])


def test_curaengine_placeholders_are_not_estimates() -> None:
    for path in (ULTI, GRIFFIN):
        meta = read_gcode(path).metadata
        assert meta["slicer"] == "Cura"
        assert "slicer_time_s" not in meta      # ";TIME:6666"
        assert "slicer_filament_mm" not in meta  # ";Filament used: 0m" (Griffin)
    real = read_gcode(b";FLAVOR:Marlin\n;TIME:6667\n;Filament used: 1.5m\n"
                      b";Generated with Cura_SteamEngine 5.9.1\nG1 X1 E1\n").metadata
    assert real["slicer_time_s"] == 6667.0 and real["slicer_filament_mm"] == 1500.0


def test_compensation_refuses_volumetric_e_naming_the_header(tmp_path: Path) -> None:
    from flowtwin.compensation import compensate

    with pytest.raises(GcodeError) as err:
        compensate(ULTI, tmp_path / "out.gcode", advance=True)
    text = str(err.value)
    assert ":1:" in text and ";FLAVOR:UltiGCode" in text and "linear E" in text
    assert not (tmp_path / "out.gcode").exists()


MACH3 = DATA / "prusaslicer_2.5_mach3.gcode.gz"


def test_an_extruder_on_axis_a_is_refused_naming_the_flavor() -> None:
    with pytest.raises(GcodeError) as err:
        read_gcode(MACH3)
    text = str(err.value)
    assert "prusaslicer_2.5_mach3.gcode.gz" in text and "gcode_flavor" in text
    assert "'mach3'" in text and "axis A" in text


@pytest.mark.parametrize(("config", "value"), [("; extrusion_axis = B\n", "'B'"),
                                               ("; gcode_flavor = machinekit\n",
                                                "'machinekit'")])
def test_other_extrusion_axes_are_refused(config: str, value: str) -> None:
    with pytest.raises(GcodeError, match=value):
        read_gcode(("G1 X10 B1.0\n" + config).encode())


def test_extrusion_axis_e_reads() -> None:
    table = read_gcode(b"G1 X10 E1.0\n; extrusion_axis = E\n; gcode_flavor = marlin2\n")
    assert float(table.moves["de"][-1]) == 1.0
