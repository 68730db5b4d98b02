"""The streamed plan against the whole-file plan: same summary and per-layer rows (sums to
the bit, times to the windows' clock rounding), spans in order, and the CLI's choice."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import flowtwin.planner.plan_stream
from flowtwin.cli.main import main
from flowtwin.errors import DataError, ProfileError
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.planner.plan_stream import plan_stream, should_stream

#: Time figures come from the windows' clocks, shifted by constant offsets: they agree to
#: the rounding of ~1e4 s clocks (1e-12 relative); everything else is equal.
TIME_REL = 1e-11


def _same_value(a: object, b: object, *, time: bool) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a):
            return math.isnan(b)
        return abs(a - b) <= (TIME_REL * max(abs(a), 1.0) if time else 0.0)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same_value(a[k], b[k], time=time) for k in a)
    return a == b


def _assert_same_plan(whole: dict[str, object], streamed: dict[str, object]) -> None:
    assert whole.keys() == streamed.keys()
    for key, val in whole.items():
        timed = key in ("total_time_s", "time_by_feature_s")
        assert _same_value(val, streamed[key], time=timed), (key, val, streamed[key])


def _assert_same_layers(whole: list[dict[str, float | int]],
                        streamed: list[dict[str, float | int]]) -> None:
    assert len(whole) == len(streamed)
    for a, b in zip(whole, streamed, strict=True):
        for key, val in a.items():
            assert _same_value(val, b[key], time=key == "time_s"), (a["layer"], key)


CASES = [("cura_5.9.1.gcode", {"klipper_config": "A.cfg"}),
         ("prusaslicer_2.7.1_benchy.gcode", {"printer": "generic-marlin"}),
         ("bambustudio_1.08_eline_multitool.gcode", {"klipper_config": "B.cfg"}),
         ("ideamaker_5.1.4.gcode", {"printer": "generic-klipper"}),
         ("arcwelder_1.2.0_on_slic3r_1.33.3_benchy.gcode", {"klipper_config": "A.cfg"}),
         ("simplify3d_4.0.0_duet.gcode", {"printer": "generic-marlin",
                                          "use_slicer_limits": True})]


@pytest.mark.corpus
@pytest.mark.parametrize(("name", "how"), CASES, ids=[c[0] for c in CASES])
def test_streamed_plan_equals_the_whole_plan(corpus_dir: Path, klipper_dir: Path, name: str,
                                             how: dict[str, object]) -> None:
    kw = dict(how)
    if "klipper_config" in kw:
        kw["klipper_config"] = klipper_dir / str(kw["klipper_config"])
    path = corpus_dir / name
    whole = plan_gcode(path, **kw)  # type: ignore[arg-type]
    st = plan_stream(path, chunk_bytes=64 * 1024, window_moves=2000, **kw)  # type: ignore[arg-type]
    spans = list(st)
    assert st.windows > 3 and st.unverified_moves == 0
    # the spans cover every move once, in order, with the whole plan's phases
    assert [s.start for s in spans] == list(np.cumsum([0] + [len(s.moves) for s in spans]))[:-1]
    phases = np.concatenate([s.phases for s in spans])
    for field in ("start_v", "cruise_v", "end_v", "accel_t", "cruise_t", "decel_t"):
        np.testing.assert_array_equal(phases[field], whole.timeline.phases[field])
    np.testing.assert_array_equal(np.concatenate([s.moves for s in spans]), whole.table.moves)
    _assert_same_plan(whole.summary().as_dict(), st.summary().as_dict())
    _assert_same_layers(whole.per_layer(), st.per_layer())


def test_results_need_the_whole_stream(corpus_dir: Path) -> None:
    st = plan_stream(corpus_dir / "kisslicer_1.1.0.5_thinbox_small.gcode")
    with pytest.raises(DataError, match="run"):
        st.summary()
    st.run()
    with pytest.raises(DataError, match="once"):
        st.run()
    with pytest.raises(DataError):
        plan_stream(corpus_dir / "cura_5.9.1.gcode", window_moves=10)


def test_file_without_moves(tmp_path: Path) -> None:
    path = tmp_path / "dwell.gcode"
    path.write_text("G4 P500\nM117 hello\n")
    whole = plan_gcode(path).summary()
    st = plan_stream(path).run()
    _assert_same_plan(whole.as_dict(), st.summary().as_dict())
    assert st.per_layer() == []


def test_marlin_delta_is_planned_in_memory(tmp_path: Path) -> None:
    path = tmp_path / "p.gcode"
    path.write_bytes(b"G1 X1 F600\n" * 10)
    assert should_stream(path, printer="anycubic-kossel", above_bytes=0) is False
    assert should_stream(path, printer="generic-marlin", above_bytes=0) is True
    assert should_stream(path, printer="generic-marlin") is False  # small
    with pytest.raises(ProfileError, match="delta"):
        plan_stream(path, printer="anycubic-kossel")


@pytest.mark.corpus
def test_cli_streams_large_files_with_the_same_output(corpus_dir: Path,
                                                      monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    path = corpus_dir / "orcaslicer_2.3.0b2.gcode"

    def run(*extra: str) -> dict[str, object]:
        with pytest.raises(SystemExit) as exc:
            main(["plan", str(path), "--json", *extra])
        assert exc.value.code == 0
        return json.loads(capsys.readouterr().out)  # type: ignore[no-any-return]

    whole = run()
    monkeypatch.setattr(flowtwin.planner.plan_stream, "STREAM_ABOVE_BYTES", 1024)
    auto = run()
    forced_whole = run("--no-stream")
    assert forced_whole == whole
    layers_w, layers_a = whole.pop("per_layer"), auto.pop("per_layer")
    _assert_same_plan(whole, auto)
    _assert_same_layers(layers_w, layers_a)  # type: ignore[arg-type]
