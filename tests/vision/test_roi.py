"""ROI parsing and validation: ``name=x,y,w,h`` strings and frame bounds."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtwin.errors import VisionError
from flowtwin.vision.roi import MIN_ROI_PX, ROI_NAMES, Roi, RoiSet, parse_roi, parse_rois


def test_parse_roi_values_and_text_round_trip() -> None:
    roi = parse_roi(" after = 398, 300,64,170 ")
    assert (roi.name, roi.x, roi.y, roi.w, roi.h) == ("after", 398, 300, 64, 170)
    assert roi.x1 == 462 and roi.y1 == 470
    assert parse_roi(roi.text()) == roi
    assert roi.center == (398 + 31.5, 300 + 84.5)


@pytest.mark.parametrize(("text", "match"), [
    ("gear", "form name=x,y,w,h"),
    ("wheel=1,2,30,40", "unknown region of interest"),
    ("gear=1,2,30", "four numbers"),
    ("gear=1,2,30,40,5", "four numbers"),
    ("gear=1,-2,30,40", "not a whole number"),
    ("gear=1,2.5,30,40", "not a whole number"),
    ("gear=1,2,3,40", "too small"),
    ("gear=a,2,30,40", "not a whole number"),
])
def test_parse_roi_errors_name_the_problem(text: str, match: str) -> None:
    with pytest.raises(VisionError, match=match) as info:
        parse_roi(text)
    assert "allowed" in str(info.value)


def test_duplicate_roi_is_an_error() -> None:
    with pytest.raises(VisionError, match="given twice"):
        parse_rois(["gear=0,0,20,20", "gear=5,5,20,20"])


def test_roi_outside_frame_names_roi_value_and_limits() -> None:
    roi = Roi("after", 600, 100, 100, 50)
    with pytest.raises(VisionError) as info:
        roi.check_inside(640, 480, source="clip.avi")
    msg = str(info.value)
    assert "clip.avi" in msg and "roi.after" in msg and "after=600,100,100,50" in msg
    assert "x + w = 700 > 640" in msg and "x + w <= 640" in msg
    roi.check_inside(700, 480)   # fits a wider frame


def test_roiset_requires_all_three_and_names_the_missing() -> None:
    rois = parse_rois(["gear=0,0,20,20", "after=30,30,20,20"])
    with pytest.raises(VisionError, match=r"missing region.*before"):
        RoiSet.from_mapping(rois, source="setup.toml")
    with pytest.raises(VisionError, match="holds the ROI named"):
        RoiSet(gear=rois["after"], before=rois["gear"], after=rois["after"])


_coord = st.integers(min_value=0, max_value=5000)
_size = st.integers(min_value=MIN_ROI_PX, max_value=5000)


@settings(max_examples=100, deadline=None)
@given(name=st.sampled_from(ROI_NAMES), x=_coord, y=_coord, w=_size, h=_size,
       pad=st.sampled_from(["", " ", "  "]))
def test_valid_rois_round_trip(name: str, x: int, y: int, w: int, h: int, pad: str) -> None:
    text = f"{pad}{name}{pad}={pad}{x},{pad}{y},{w}{pad},{h}{pad}"
    roi = parse_roi(text)
    assert (roi.name, roi.x, roi.y, roi.w, roi.h) == (name, x, y, w, h)
    assert parse_roi(roi.text()) == roi


@settings(max_examples=150, deadline=None)
@given(text=st.text(alphabet=st.characters(codec="utf-8"), max_size=40)
       | st.from_regex(r"[a-z]{0,7}=[-0-9., ]{0,20}", fullmatch=True))
def test_any_text_parses_or_raises_vision_error(text: str) -> None:
    """No input makes the parser fail with anything but a VisionError."""
    try:
        roi = parse_roi(text)
    except VisionError as exc:
        assert exc.allowed or exc.field
    else:
        assert roi.name in ROI_NAMES and roi.w >= MIN_ROI_PX and roi.h >= MIN_ROI_PX
