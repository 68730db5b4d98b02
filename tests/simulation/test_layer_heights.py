"""Layer heights of moves: planar layers, spirals with and without slicer markers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import read_gcode
from flowtwin.profiles.machine import load_machine
from flowtwin.simulation import simulate, simulate_stream
from flowtwin.simulation.parameters import (
    THIN_LAYER_FRACTION,
    layer_heights_mm,
    thin_layer_moves,
)

PITCH_MM = 0.2      # Z rise per turn of the spiral (the nominal layer height)
SEGMENTS = 48       # moves per turn: steps of 0.2 / 48 ≈ 4 µm, like FullControl's vases
RADIUS_MM = 10.0
E_PER_MM = 0.0333   # ~0.45 × 0.2 mm bead on 1.75 mm filament


def _spiral_gcode(*, markers: bool, turns: int = 3) -> str:
    """Two planar square layers at 0.2 and 0.4 mm, then a spiral wall from 0.4 mm rising
    ``PITCH_MM`` per turn; ``markers``: PrusaSlicer's layer markers, one per turn."""
    out = ["G21", "G90", "M83", "M104 S210", "G92 E0", "G1 Z0.2 F600",
           "G1 X100 Y100 F6000"]
    for z in (0.2, 0.4):
        if markers:
            out += [";LAYER_CHANGE", f";Z:{z:.3f}", f";HEIGHT:{PITCH_MM:.3f}"]
        out.append(f"G1 Z{z:.3f} F600")
        for x, y in ((120, 100), (120, 120), (100, 120), (100, 100)):
            out.append(f"G1 X{x} Y{y} E{20 * E_PER_MM:.5f} F1800")
    cx, cy = 110.0, 110.0
    out.append(f"G1 X{cx + RADIUS_MM:.3f} Y{cy:.3f} F6000")
    step = 2.0 * math.pi * RADIUS_MM / SEGMENTS
    z0 = 0.4
    for t in range(turns):
        if markers:
            out += [";LAYER_CHANGE", f";Z:{z0 + (t + 1) * PITCH_MM:.3f}",
                    f";HEIGHT:{PITCH_MM:.3f}"]
        for k in range(1, SEGMENTS + 1):
            a = 2.0 * math.pi * k / SEGMENTS
            z = z0 + t * PITCH_MM + PITCH_MM * k / SEGMENTS
            out.append(f"G1 X{cx + RADIUS_MM * math.cos(a):.4f} "
                       f"Y{cy + RADIUS_MM * math.sin(a):.4f} Z{z:.5f} "
                       f"E{step * E_PER_MM:.5f} F1800")
    out += ["G1 E-1 F2400", "G1 Z30 F600"]
    return "\n".join(out) + "\n"


def _spiral_rows(table: object) -> np.ndarray:
    m = table.moves  # type: ignore[attr-defined]
    ext = (m["kind"] & MoveKind.EXTRUDE) != 0
    return np.flatnonzero(ext & (m["z"] > 0.4 + 1e-9))


def test_unmarked_spiral_gets_the_nominal_height_and_planar_layers_their_rise() -> None:
    table = read_gcode(_spiral_gcode(markers=False).encode())
    spiral = _spiral_rows(table)
    assert spiral.size == 3 * SEGMENTS
    # without markers the reader makes a layer of every rising move (docs/gcode.md)
    assert np.unique(table.moves["layer"][spiral]).size == spiral.size
    for default in (0.2, 0.3):  # the substitute is the nominal height given, not a guess
        h = layer_heights_mm(table, default_mm=default, max_mm=0.4)
        np.testing.assert_allclose(h[spiral], default)
        assert thin_layer_moves(table, default_mm=default, max_mm=0.4) == spiral.size
    # planar layers keep their measured rise: 0.2 over the bed, 0.2 over the first layer
    h = layer_heights_mm(table, default_mm=0.3, max_mm=0.4)
    m = table.moves
    planar = np.flatnonzero(((m["kind"] & MoveKind.EXTRUDE) != 0) & (m["z"] <= 0.4 + 1e-9))
    np.testing.assert_allclose(h[planar], 0.2, atol=1e-6)


def test_marked_spiral_layer_is_measured_from_its_top() -> None:
    """With markers, a spiral turn is one layer; its height is its top over the turn
    below (PITCH_MM), not where its first step ends (PITCH_MM / SEGMENTS)."""
    table = read_gcode(_spiral_gcode(markers=True).encode())
    spiral = _spiral_rows(table)
    assert np.unique(table.moves["layer"][spiral]).size == 3
    h = layer_heights_mm(table, default_mm=0.3, max_mm=0.4)
    np.testing.assert_allclose(h[spiral], PITCH_MM, atol=1e-6)
    assert thin_layer_moves(table, default_mm=0.3, max_mm=0.4) == 0


def test_threshold_is_a_fraction_of_the_nominal_height() -> None:
    # a 4 µm step is thin for any plausible nominal height; with a nominal height below
    # step / fraction it would be a layer of its own (no substitution)
    table = read_gcode(_spiral_gcode(markers=False).encode())
    step = PITCH_MM / SEGMENTS
    tiny_default = 0.9 * step / THIN_LAYER_FRACTION
    assert thin_layer_moves(table, default_mm=tiny_default, max_mm=0.4) == 0


@pytest.fixture(scope="module")
def unmarked_spiral(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spiral") / "spiral.gcode"
    path.write_text(_spiral_gcode(markers=False, turns=90))  # 4320 spiral moves
    return path


def test_simulation_warns_and_stream_agrees(unmarked_spiral: Path) -> None:
    whole = simulate(unmarked_spiral)
    assert any("spiral without layer markers" in w for w in whole.warnings)
    spiral = _spiral_rows(whole.plan.table)
    h = whole.parameters.layer_height_mm
    nominal = load_machine("tronvoll2019").setup.layer_height_mm or 0.2  # the twin's default
    np.testing.assert_allclose(h[spiral], nominal)  # no µm gaps reach the physics
    # streaming sees layer tops only as they come, and must reach the same heights
    st = simulate_stream(unmarked_spiral, chunk_bytes=16 * 1024, section_moves=1000)
    assert st.sections >= 2  # a spiral has no rest: the section is cut mid-wall
    a, b = whole.summary(), st.summary().figures
    for x, y in ((a.delivered_volume_mm3, b.delivered_volume_mm3),
                 (a.rms_flow_error, b.rms_flow_error), (a.max_feed_force_n, b.max_feed_force_n)):
        assert abs(y - x) <= 1e-9 * max(abs(x), 1e-9)


def test_layer_top_z_matches_numpy_maximum_at():
    # the compiled per-layer maximum must be np.maximum.at's (NaN wins, -inf: no extrusion)
    from flowtwin.simulation.parameters import _layer_top_z

    rng = np.random.default_rng(7)
    n, n_layers = 5000, 40
    layer = rng.integers(-1, n_layers - 5, n).astype(np.int32)  # some layers stay empty
    z = rng.uniform(0.0, 10.0, n)
    z[rng.random(n) < 0.002] = np.nan
    kind = rng.integers(0, 16, n).astype(np.uint8)
    bits = int(MoveKind.EXTRUDE | MoveKind.XY)
    ext = (kind & bits) == bits
    ref = np.full(n_layers, -np.inf)
    sel = ext & (layer >= 0)
    with np.errstate(invalid="ignore"):  # (NaN is meant)
        np.maximum.at(ref, layer[sel], z[sel])
    got = _layer_top_z(layer, z, kind, bits, n_layers)
    assert np.isnan(ref).any() and np.isneginf(ref).any()  # both special cases occur
    assert got.tobytes() == ref.tobytes()


GRIFFIN = (Path(__file__).resolve().parents[1] / "data" / "slicer_flavors"
           / "curaengine_4.13_griffin.gcode.gz")


def test_an_unretraction_at_the_next_layers_z_does_not_make_a_layer_top() -> None:
    # CuraEngine (Griffin flavor) travels to the next layer's Z and un-retracts (E only)
    # before that layer's ";LAYER:n": the printing moves give each layer's top
    table = read_gcode(GRIFFIN)
    h = layer_heights_mm(table, default_mm=0.15, max_mm=0.4)
    mv = table.moves
    printing = ((mv["kind"] & MoveKind.EXTRUDE) != 0) & ((mv["kind"] & MoveKind.XY) != 0)
    assert thin_layer_moves(table, default_mm=0.15, max_mm=0.4) == 0
    first = printing & (mv["layer"] == 0)
    rest = printing & (mv["layer"] > 0)
    assert np.allclose(h[first], 0.3) and np.allclose(h[rest], 0.2)  # its 0.3 / 0.2 mm layers


def _square(z: float) -> list[str]:
    return [f"G1 Z{z:.2f} F600"] + [f"G1 X{x} Y{y} E0.5 F1800"
                                    for x, y in ((110, 100), (110, 110), (100, 110), (100, 100))]


def test_the_next_object_of_a_sequential_print_lies_on_the_bed() -> None:
    out = ["G90", "M83", "G1 X100 Y100 F6000"]
    for _object in range(2):  # two objects of three 0.2 mm layers, printed one after the other
        for k in range(3):
            out += [";LAYER_CHANGE", *_square(0.2 * (k + 1))]
        out.append("G1 Z5 F600")
    table = read_gcode(("\n".join(out) + "\n").encode())
    h = layer_heights_mm(table, default_mm=0.15, max_mm=0.4)
    mv = table.moves
    printing = (mv["kind"] & MoveKind.EXTRUDE) != 0
    assert np.allclose(h[printing], 0.2)
    assert thin_layer_moves(table, default_mm=0.15, max_mm=0.4) == 0
