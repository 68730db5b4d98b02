"""Streaming simulation against the whole-table simulation and bounded sections."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.errors import DataError, GcodeError
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.reader import iter_move_chunks
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg
from flowtwin.planner.windows import WindowPlanner
from flowtwin.simulation import SimulationResult, StreamResult, simulate, simulate_stream

# Whole-print figures are sums over ~1e5 moves of per-move values that agree to rounding:
# 1e-9 relative leaves room for the summation order and the clock offsets of the windows
# (1e-10 s on a 4600 s print) while any wrong section border or state carry shows at 1e-6
# or worse.
REL = 1e-9


def _assert_same(whole: dict[str, object], stream: dict[str, object]) -> None:
    for key, val in whole.items():
        got = stream[key]
        if isinstance(val, float):
            assert isinstance(got, float), key
            scale = abs(val) if key != "ooze_volume_mm3" else abs(whole["delivered_volume_mm3"])  # type: ignore[arg-type]
            assert abs(got - val) <= REL * max(scale, 1e-9), key
        else:
            assert got == val, key


def _rows_same(a: list[dict[str, object]], b: list[dict[str, object]], total: float) -> None:
    assert len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        for key, val in ra.items():
            if isinstance(val, float):
                # per-row values relative to the row's command, or the print's for ~0 rows
                scale = max(abs(float(ra["commanded_mm3"])), 1e-6 * total)  # type: ignore[arg-type]
                assert abs(float(rb[key]) - val) <= 1e-8 * max(scale, abs(val)), key  # type: ignore[arg-type]
            else:
                assert rb[key] == val, key


@pytest.fixture(scope="module")
def gen_gcode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("stream") / "gen.gcode"
    write_print(path, PrintSpec(layers=30, infill_density=1.0))
    return path


def test_stream_equals_whole_simulation_on_generated_print(gen_gcode: Path) -> None:
    whole = simulate(gen_gcode)
    st = simulate_stream(gen_gcode, chunk_bytes=16 * 1024, section_moves=1000)
    assert st.sections > 3 and st.windows > 3  # the test crosses many borders
    assert st.unverified_moves == 0
    _assert_same(whole.summary().as_dict(), st.summary().as_dict())
    total = whole.summary().commanded_volume_mm3
    _rows_same(whole.per_layer(), st.per_layer(), total)  # type: ignore[arg-type]
    _rows_same(whole.per_feature(), st.per_feature(), total)  # type: ignore[arg-type]
    _worst_same(whole, st)


def _worst_same(whole: SimulationResult, st: StreamResult) -> None:
    """The streamed ranking of the worst moves is the whole print's: the same scores in the
    same order, each row the whole table's move (moves whose scores agree to rounding may
    swap places: prints repeat the same move many times)."""
    everything = {r["move"]: r for r in whole.worst_moves("width", len(whole.metrics))}
    everything.update({r["move"]: r for r in whole.worst_moves("force", len(whole.metrics))})
    for by, count in (("width", 10), ("force", 20)):
        a, b = whole.worst_moves(by, count), st.worst_moves(by, count)
        assert len(a) == len(b)

        def score(r: dict[str, float | int], by: str = by) -> float:
            return (abs(float(r["width_mean_mm"]) - float(r["width_nominal_mm"]))
                    if by == "width" else float(r["force_margin_n"]))

        for ra, rb in zip(a, b, strict=True):
            assert score(rb) == pytest.approx(score(ra), rel=1e-9), by
            ref = everything[int(rb["move"])]
            for key, val in ref.items():
                assert rb[key] == pytest.approx(val, rel=1e-9, abs=1e-12), (by, key)


@pytest.mark.corpus
def test_stream_equals_whole_with_klipper_smoothed_advance(corpus_dir: Path,
                                                           klipper_dir: Path) -> None:
    path = corpus_dir / "cura_5.9.1.gcode"
    cfg = klipper_dir / "B.cfg"   # pressure_advance 0.04 s, smooth time 0.04 s
    whole = simulate(path, klipper_config=cfg)
    st = simulate_stream(path, klipper_config=cfg, chunk_bytes=128 * 1024,
                         section_moves=5000)
    assert st.sections > 3
    assert st.cuts_not_at_rest == 0 and st.unverified_moves == 0
    _assert_same(whole.summary().as_dict(), st.summary().as_dict())
    _worst_same(whole, st)


@pytest.mark.corpus
def test_windowed_plan_is_bit_identical(corpus_dir: Path, klipper_dir: Path) -> None:
    path = corpus_dir / "orcaslicer_2.3.0b2.gcode"
    ks = load_printer_cfg(klipper_dir / "A.cfg")
    opts = klipper_read_options(ks)
    whole = simulate(path, klipper_config=klipper_dir / "A.cfg").plan.timeline
    wp = WindowPlanner(lambda t: plan_klipper(t, ks), str(path), np.zeros(4),
                       window_moves=5000)
    spans = []
    for chunk in iter_move_chunks(path, options=opts, chunk_bytes=64 * 1024):
        spans += wp.feed(chunk)
    spans += wp.finish()
    ph = np.concatenate([s.phases for s in spans])
    assert wp.windows > 3
    for name in ("start_v", "cruise_v", "end_v", "accel", "accel_t", "cruise_t", "decel_t"):
        np.testing.assert_array_equal(ph[name], whole.phases[name])
    # the clock: windows are shifted by a constant, so times agree to rounding of ~1e4 s
    np.testing.assert_allclose(ph["t_start"], whole.phases["t_start"], rtol=0, atol=1e-8)
    assert spans[-1].end_time_s == pytest.approx(whole.total_time_s, rel=1e-12)


def test_stream_refusals(gen_gcode: Path, tmp_path: Path) -> None:
    with pytest.raises(DataError):
        simulate_stream(gen_gcode, section_moves=10)
    empty = tmp_path / "empty.gcode"
    empty.write_text("; nothing\n")
    with pytest.raises(GcodeError):
        simulate_stream(empty)


@pytest.mark.corpus
def test_stream_carries_marlin_linear_advance(corpus_dir: Path) -> None:
    # the default set-up plans with Marlin; this file sets M900 K0.2 (Linear Advance 1.5):
    # the tracked advance crosses every section border
    path = corpus_dir / "prusaslicer_2.7.1_benchy.gcode"
    whole = simulate(path)
    assert whole.dynamics.feed.advance == "marlin"
    st = simulate_stream(path, section_moves=20_000)
    assert st.sections > 3 and st.unverified_moves == 0
    _assert_same(whole.summary().as_dict(), st.summary().as_dict())


@pytest.mark.corpus
def test_cli_streams_large_files_with_the_same_output(corpus_dir: Path,
                                                      monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    """Above the size threshold ``flowtwin simulate`` streams on its own and prints the same
    JSON object (the same keys; figures to the stream's rounding)."""
    import json

    import flowtwin.planner.plan_stream
    from flowtwin.cli.main import main

    path = corpus_dir / "orcaslicer_2.3.0b2.gcode"

    def run(*extra: str) -> dict[str, object]:
        with pytest.raises(SystemExit) as exc:
            main(["simulate", str(path), "--json", *extra])
        assert exc.value.code == 0
        return json.loads(capsys.readouterr().out)  # type: ignore[no-any-return]

    whole = run("--no-fit")
    whole.pop("verdict")  # the verdict (windowed figures, places) needs the whole tables
    monkeypatch.setattr(flowtwin.planner.plan_stream, "STREAM_ABOVE_BYTES", 1024)
    auto = run()
    assert auto.keys() == whole.keys()
    _assert_same(whole, auto)
    assert "stream_sections" in run("--stream")  # asked for: with the stream's counts
    # what streaming cannot give keeps the whole-table path
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(path), "--stream", "--series", "x.csv"])
    assert exc.value.code == 2
