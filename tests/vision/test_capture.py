"""Frame sources: capture timestamps and every kind of bad input."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from flowtwin.errors import VisionError
from flowtwin.vision import Frame, Quality, SourceInfo, measure, measure_frames, open_source
from flowtwin.vision.capture import read_timestamps_file
from flowtwin.vision.synth import (
    MotionSeries,
    SceneSpec,
    timestamps_text,
    write_image_folder,
    write_video,
)

from .conftest import render

FPS = 30.0


@pytest.fixture(scope="module")
def frames():
    scene = SceneSpec(dropped_frames=(5,), seed=2)
    return scene, render(scene, MotionSeries.constant(duration_s=15 / FPS,
                                                      gear_speed_mm_s=2.0, slip=0.1))


def test_video_times_come_from_the_container_or_the_sidecar(tmp_path: Path, frames) -> None:
    scene, frs = frames
    plain = write_video(frs, tmp_path / "plain.avi", fps=FPS, fourcc="MJPG",
                        timestamps="never")
    with open_source(plain) as src:
        got = [f.t_s for f in src]
        assert src.timestamp_source.startswith("container")
        assert src.frames_expected == len(frs) == 15 and src.width_px == 640
    # a constant-rate container cannot know that frame 5 was dropped
    np.testing.assert_allclose(got, np.arange(15) / FPS, atol=1e-9)
    side = write_video(frs, tmp_path / "side.avi", fps=FPS, fourcc="FFV1")
    with open_source(side) as src:
        got = [f.t_s for f in src]
        assert src.timestamp_source.startswith("timestamp file")
    np.testing.assert_allclose(got, [f.t_s for f in frs], atol=1e-9)
    res = measure(side, scene.vision_config())
    assert res.summary.dropped_frames == 1 and res.summary.gap_frames == 1
    # an explicit timestamp file wins over the sidecar
    other = tmp_path / "other.txt"
    other.write_text(timestamps_text([0.5 + 0.04 * k for k in range(15)]))
    with open_source(side, timestamps=other) as src:
        assert [f.t_s for f in src][1] == pytest.approx(0.54)


def test_timestamp_file_errors_name_line_and_value(tmp_path: Path, frames) -> None:
    _, frs = frames
    video = write_video(frs, tmp_path / "v.avi", fps=FPS, fourcc="MJPG", timestamps="never")
    bad = tmp_path / "bad.txt"
    bad.write_text("# timestamp format v2\n0\n33.3\nabc\n")
    with pytest.raises(VisionError, match=r"bad.txt:4.*'abc'"):
        read_timestamps_file(bad)
    bad.write_text("0\n40\n40\n")
    with pytest.raises(VisionError, match=r"bad.txt:3: timestamps must increase"):
        read_timestamps_file(bad)
    short = tmp_path / "short.txt"
    short.write_text("0\n33\n66\n")
    with pytest.raises(VisionError, match="more frames than the timestamp file"):
        measure(video, SceneSpec().vision_config(), timestamps=short)
    with pytest.raises(VisionError, match="timestamp file not found"):
        open_source(video, timestamps=tmp_path / "missing.txt")


def test_image_folder_with_timestamps_and_with_mtimes(tmp_path: Path, frames) -> None:
    scene, frs = frames
    folder = write_image_folder(frs, tmp_path / "imgs")
    res = measure(folder, scene.vision_config())
    assert res.summary.source_kind == "images" and res.summary.frames == 15
    assert res.summary.timestamp_source.startswith("timestamp file")
    assert res.summary.dropped_frames == 1
    assert res.summary.filament_speed_mm_s == pytest.approx(1.8, rel=0.02)
    # without the file: modification times (set here to the capture times)
    (folder / "timestamps.txt").unlink()
    for k, f in enumerate(sorted(folder.glob("*.png"))):
        ns = 1_700_000_000_000_000_000 + int(frs[k].t_s * 1e9)
        os.utime(f, ns=(ns, ns))
    with open_source(folder) as src:
        assert src.timestamp_source == "file modification times"
        got = [f.t_s for f in src]
    np.testing.assert_allclose(np.diff(got), np.diff([f.t_s for f in frs]), atol=1e-6)
    last = sorted(folder.glob("*.png"))[-1]
    os.utime(last, ns=(1_600_000_000_000_000_000,) * 2)
    with pytest.raises(VisionError, match="modification times do not increase"):
        open_source(folder)


def test_unreadable_inputs_give_clear_errors(tmp_path: Path, frames) -> None:
    _, frs = frames
    with pytest.raises(VisionError, match="no such file or folder"):
        open_source(tmp_path / "nope.avi")
    text = tmp_path / "notes.avi"
    text.write_text("this is not a video\n" * 20)
    with pytest.raises(VisionError, match=r"notes.avi: cannot open the video"):
        measure(text, SceneSpec().vision_config())
    empty = tmp_path / "empty.avi"
    empty.write_bytes(b"")
    with pytest.raises(VisionError, match="video file is empty"):
        open_source(empty)
    (tmp_path / "none").mkdir()
    with pytest.raises(VisionError, match="holds no images"):
        open_source(tmp_path / "none")
    folder = write_image_folder(frs[:3], tmp_path / "imgs")
    (folder / "frame_000001.png").write_text("not a png")
    with pytest.raises(VisionError, match=r"frame_000001.png: not a readable image"):
        list(open_source(folder))
    small = tmp_path / "mixed"
    write_image_folder(frs[:2], small)
    cv2.imwrite(str(small / "frame_000002.png"), np.zeros((100, 100), np.uint8))
    (small / "timestamps.txt").write_text(timestamps_text([0.0, 0.033, 0.066]))
    with pytest.raises(VisionError, match="frame size changed"):
        list(open_source(small))
    with pytest.raises(VisionError, match="camera 7: the camera could not be opened"):
        open_source(7, max_frames=2)
    with pytest.raises(VisionError, match="needs a frame limit"):
        open_source(7)


def test_truncated_and_corrupt_videos_are_reported_not_filled_in(tmp_path: Path) -> None:
    scene = SceneSpec(seed=12)
    frs = render(scene, MotionSeries.constant(duration_s=15 / FPS, gear_speed_mm_s=2.0,
                                              slip=0.1))
    video = write_video(frs, tmp_path / "full.avi", fps=FPS, fourcc="MJPG")
    data = video.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) // 2])
    res = measure(cut, scene.vision_config())
    s = res.summary
    assert s.truncated and s.frames_expected == 16 and 3 <= s.frames < 16
    # what was decoded is measured; nothing is invented for the missing part
    assert len(res.series) == s.frames
    assert s.filament_speed_mm_s == pytest.approx(1.8, rel=0.03)
    assert s.gear_speed_mm_s == pytest.approx(2.0, rel=0.03)
    # a damaged stretch: FFmpeg conceals it with the previous frame's pixels; those
    # regions are recognised as stale, and every value that is reported is right
    garbled = bytearray(data)
    garbled[len(data) // 3: len(data) // 3 + 30000] = bytes(30000)
    bad = tmp_path / "garbled.avi"
    bad.write_bytes(bytes(garbled))
    res = measure(bad, scene.vision_config())
    se = res.series
    damaged = (se.flags & int(Quality.FILAMENT_STALE | Quality.GEAR_STALE
                              | Quality.GEAR_LOW_TEXTURE | Quality.FILAMENT_LOW_TEXTURE
                              | Quality.GEAR_TRACKING | Quality.FILAMENT_TRACKING)) != 0
    assert damaged.sum() >= 1
    t = np.array([f.t_s for f in frs])[: len(se)]
    s_true = np.array([f.filament_distance_mm for f in frs])[: len(se)]
    ok = np.isfinite(se.filament_speed_mm_s)
    assert ok.sum() >= len(se) - 4
    # each valid step, however long its span, matches the true mean speed over it
    assert np.all(np.abs(se.filament_speed_mm_s[ok] - 1.8) <= 0.05 * 1.8)
    assert np.allclose(np.diff(s_true) / np.diff(t), 1.8)


def test_roi_outside_frame_and_non_increasing_times(frames) -> None:
    scene, frs = frames
    cfg = scene.vision_config()
    import dataclasses

    from flowtwin.vision import Roi, RoiSet
    wide = dataclasses.replace(cfg, rois=RoiSet(cfg.rois.gear, cfg.rois.before,
                                                Roi("after", 600, 300, 64, 170)))
    seq = [Frame(f.index, f.t_s, f.image) for f in frs]
    with pytest.raises(VisionError, match=r"ROI 'after' extends beyond the 640×480 frame"):
        measure_frames(seq, wide, frame_size=(640, 480), info=SourceInfo("clip.avi"))
    back = [seq[0], seq[1], Frame(2, seq[1].t_s, seq[2].image)]
    with pytest.raises(VisionError, match="frame 2: capture timestamps do not increase"):
        measure_frames(back, cfg, frame_size=(640, 480), info=SourceInfo("clip.avi"))
    nosc = dataclasses.replace(cfg, mm_per_px=None)
    with pytest.raises(VisionError, match="no image scale given"):
        measure_frames(seq, nosc, frame_size=(640, 480))
