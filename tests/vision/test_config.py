"""Vision TOML files and option merging: bounds, unknown keys, clear errors."""

from __future__ import annotations

from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtwin.errors import VisionError
from flowtwin.vision.config import TrackingParams, VisionConfig, build_config, load_config_file
from flowtwin.vision.roi import parse_rois

GOOD = """
[roi]
gear = [80, 90, 220, 300]
before = [372, 10, 116, 130]
after = [398, 300, 64, 170]

[scale]
mm_per_px = 0.02

[gear]
center_px = [190.25, 240.0]
radius_mm = 3.92

[filament]
direction = "up"

[tracking]
max_tracks = 25
fb_max_px = 0.4
"""


def test_full_file_and_cli_overrides(tmp_path: Path) -> None:
    path = tmp_path / "cam.toml"
    path.write_text(GOOD)
    cfg = build_config(config_path=path)
    assert cfg.rois.after.text() == "after=398,300,64,170"
    assert cfg.mm_per_px == 0.02 and cfg.calib_width_mm is None
    assert cfg.gear_center_px == (190.25, 240.0) and cfg.gear_radius_mm == 3.92
    assert cfg.direction == "up" and cfg.gear_mode == "rotation"
    assert cfg.tracking.max_tracks == 25 and cfg.tracking.fb_max_px == 0.4
    # explicit options win; a CLI scale replaces the file's scale entirely
    cfg2 = build_config(config_path=path, rois=parse_rois(["after=10,10,30,40"]),
                        calib_width_mm=1.75, direction="down", tracking={"max_tracks": 12})
    assert cfg2.rois.after.text() == "after=10,10,30,40"
    assert cfg2.rois.gear.text() == "gear=80,90,220,300"
    assert cfg2.mm_per_px is None and cfg2.calib_width_mm == 1.75
    assert cfg2.direction == "down" and cfg2.tracking.max_tracks == 12


@pytest.mark.parametrize(("text", "match"), [
    ("[rois]\ngear = [1, 2, 30, 40]\n", "unknown table"),
    ("[roi]\ngears = [1, 2, 30, 40]\n", "unknown key"),
    ("[scale]\nmm_per_pixel = 0.02\n", "unknown key"),
    ("[scale]\nmm_per_px = -0.02\n", "out of range"),
    ("[scale]\nmm_per_px = 'big'\n", "expected a number"),
    ("[roi]\ngear = [1, 2, 30]\n", "list of four integers"),
    ("[roi]\ngear = [1, 2, 30.5, 40]\n", "integer pixel count"),
    ("[tracking]\nwin_px = 16\n", "odd side"),
    ("[tracking]\nmax_tracks = 1\n", "out of range"),
    ("[tracking]\nmax_tracks = 10.0\n", "wrong type"),
    ("[gear]\ncenter_px = [1]\n", r"\[x, y\]"),
    ("[filament]\ndirection = 'sideways'\n", "unknown filament direction"),
    ("filament = 3\n", "must be a table"),
    ("[roi\n", "not valid TOML"),
])
def test_bad_files_name_file_field_and_allowed(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.toml"
    rois = "[roi]\ngear = [0, 0, 20, 20]\nbefore = [0, 0, 20, 20]\nafter = [0, 0, 20, 20]\n"
    path.write_text(text if text.startswith("[roi") else text + "\n" + rois)
    with pytest.raises(VisionError, match=match) as info:
        build_config(config_path=path)
    assert str(path) in str(info.value)


def test_conflicts_and_missing_things() -> None:
    rois = parse_rois(["gear=0,0,20,20", "before=0,0,20,20", "after=0,0,20,20"])
    with pytest.raises(VisionError, match="not both"):
        build_config(rois=rois, mm_per_px=0.02, calib_width_mm=1.75)
    with pytest.raises(VisionError, match="gear radius given in tangential mode"):
        build_config(rois=rois, gear_radius_mm=4.0, gear_method="tangential")
    with pytest.raises(VisionError, match="does not use the gear centre"):
        build_config(rois=rois, gear_center_px=(1.0, 2.0), gear_method="tangential")
    with pytest.raises(VisionError, match="unknown gear mode"):
        build_config(rois=rois, gear_method="spin")  # type: ignore[arg-type]
    with pytest.raises(VisionError, match="missing region"):
        build_config(rois={"gear": rois["gear"]})
    with pytest.raises(VisionError, match="unknown tracking parameter"):
        build_config(rois=rois, tracking={"speed": 3})
    with pytest.raises(VisionError, match="cannot read"):
        load_config_file("/nonexistent/cam.toml")
    cfg = build_config(rois=rois)
    # no centre: estimated from the motion, tangential if that shows no rotation
    assert isinstance(cfg, VisionConfig) and cfg.gear_mode == "auto"
    assert build_config(rois=rois, gear_radius_mm=4.0).gear_radius_mm == 4.0
    assert cfg.tracking == TrackingParams()


_value = st.one_of(st.integers(-5, 5000), st.floats(-10, 1e4, allow_nan=False),
                   st.text(max_size=5), st.booleans(),
                   st.lists(st.integers(-5, 700), max_size=5))
_table = st.dictionaries(
    st.sampled_from(["gear", "before", "after", "mm_per_px", "calib_width_mm", "center_px",
                     "radius_mm", "direction", "max_tracks", "win_px", "other"]),
    _value, max_size=4)
_doc = st.dictionaries(st.sampled_from(["roi", "scale", "gear", "filament", "tracking",
                                        "extra"]), _table, max_size=4)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(doc=_doc)
def test_any_toml_document_loads_or_raises_vision_error(tmp_path: Path, doc: dict) -> None:
    """Whatever the file holds, loading gives a config or a VisionError naming the file."""
    path = tmp_path / "fuzz.toml"
    path.write_text(tomli_w.dumps(doc))
    try:
        cfg = build_config(config_path=path)
    except VisionError as exc:
        assert exc.source == str(path) or exc.field is not None
    else:
        assert set(doc["roi"]) >= {"gear", "before", "after"}
        assert cfg.tracking.win_px % 2 == 1
