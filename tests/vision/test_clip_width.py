"""Width over a whole recording (flowtwin.vision.clip_width): one blur and limb shape per
clip, and the refusals a single frame cannot make."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from flowtwin.vision import Quality, Roi, RoiSet, VisionConfig, measure
from flowtwin.vision.clip_width import FrameGroups, contact_rows, is_clean

from .realcam import DriveProfile, RigSpec, render_clip, write_mpeg4


def test_contact_rows_known_answer() -> None:
    # a gear of contact radius 190 px whose teeth reach 10 px further covers the edge
    # where the circle of radius 200 is beyond it: |y − y_c| < √(200² − 190²) = 62.45
    y0, y1 = contact_rows((100.0, 200.0), 190.0, 10.0)
    assert y0 == pytest.approx(200.0 - math.sqrt(200.0 ** 2 - 190.0 ** 2))
    assert y1 == pytest.approx(200.0 + 62.44997998)
    assert contact_rows((0.0, 50.0), 100.0, 0.0) == (50.0, 50.0)


def test_clean_edges_and_rough_ones() -> None:
    # measured clip medians (clip_width's docstring): clean silhouettes 0.25-0.5 px on
    # the real clip, 0.67 px at 2 px blur on renderer 2; teeth over one edge 0.63-1.4 px
    # against 0.2 px on the other; teeth marks 1.6-2.3 px
    assert is_clean((0.44, 0.35)) and is_clean((0.67, 0.55)) and is_clean((0.95, 0.75))
    assert not is_clean((0.63, 0.18)) and not is_clean((1.1, 0.19))
    assert not is_clean((1.6, 0.8)) and not is_clean((2.3, 1.0))


def test_frame_groups_average_consecutive_frames_whose_edges_stay_put() -> None:
    lines = ((0.0, 10.0), (0.0, 50.0))
    moved = ((0.0, 10.0), (0.0, 50.8))          # right edge 0.8 px away: a new group
    groups = FrameGroups(size=4, keep=2)
    for k in range(4):                            # one full group: the mean of 0..3
        groups.add(np.full((6, 60), k, np.uint8), lines)
    assert len(groups.means) == 1 and np.all(groups.means[0] == 1.5)
    groups.add(np.full((6, 60), 10, np.uint8), lines)
    groups.add(np.full((6, 60), 20, np.uint8), lines)
    groups.add(np.full((6, 60), 40, np.uint8), moved)   # closes 10, 20 (half a group)
    assert len(groups.means) == 2 and np.all(groups.means[1] == 15.0)
    groups.close()                                       # a single frame: dropped
    assert len(groups.means) == 2
    for k in range(12):                                  # more than 2·keep: thinned out
        groups.add(np.full((6, 60), k, np.uint8), lines)
    assert 2 <= len(groups.means) <= 4


@pytest.fixture(scope="module")
def rig_clip(tmp_path_factory: pytest.TempPathFactory) -> tuple[RigSpec, Path]:
    spec = RigSpec(seed=3)
    frames = render_clip(spec, DriveProfile((0.0, 1.0), (2.0, 2.0), (0.1, 0.1)), 24)
    return spec, write_mpeg4(frames, tmp_path_factory.mktemp("rig") / "c.avi", spec.fps)


def _before(spec: RigSpec, y: int, h: int) -> Roi:
    xl = spec.filament_x_px - spec.radius_px
    return Roi("before", int(xl - 20), y, int(2 * spec.radius_px + 40), h)


def test_a_before_roi_in_the_gears_contact_zone_is_refused(
        rig_clip: tuple[RigSpec, Path]) -> None:
    """With the gear axis known, rows where the teeth reach the filament's edge are
    refused whatever the image says; above them the width is measured."""
    spec, path = rig_clip
    cx, cy = spec.gear_center_px
    face = Roi("gear", int(cx - 60), int(cy - 100), 120, 200)
    after = Roi("after", int(spec.filament_x_px - spec.radius_px + 20), 330,
                int(2 * spec.radius_px - 40), 140)

    def run(before: Roi, center: tuple[float, float] = (cx, cy)):
        cfg = VisionConfig(rois=RoiSet(face, before, after), mm_per_px=spec.mm_per_px,
                           diameter_mm=spec.filament_diameter_mm, gear_center_px=center,
                           gear_radius_mm=spec.drive_radius_mm)
        return measure(path, cfg)

    clear = run(_before(spec, 20, 100)).summary
    assert clear.width_note is None and clear.width_valid_frames == 24
    res = run(_before(spec, int(cy) - 40, 60))
    s = res.summary
    assert s.width_valid_frames == 0 and s.width_note is not None
    assert np.all(res.series.flags & int(Quality.WIDTH_INVALID | Quality.WIDTH_AMBIGUOUS))
    assert any(w.startswith("width refused in every frame") for w in s.warnings)
    # just above the teeth's reach (the bite is 0.1 mm, the guard 0.25 mm) the image
    # itself is clean, yet the rows are within the guard: refused by the gear's geometry
    r_c = spec.filament_x_px - spec.radius_px - cx
    y_guard = contact_rows((cx, cy), r_c, 0.25 / spec.mm_per_px)[0]
    y_bite = contact_rows((cx, cy), r_c, spec.bite_mm / spec.mm_per_px)[0]
    near = _before(spec, int(y_guard) - 20, 30)
    assert near.y1 < y_bite - 10
    res = run(near)
    s = res.summary
    assert s.width_note is not None and "contact zone" in s.width_note
    assert s.width_valid_frames == 0
    # the same rows with the axis 150 px lower (its zone far below them) are measured:
    # the refusal above came from the geometry, not from the image
    moved = run(near, (cx, cy + 150)).summary
    assert moved.width_note is None and moved.width_valid_frames == 24
    assert moved.width_mm == pytest.approx(spec.filament_diameter_mm,
                                           abs=spec.width_wave_mm + 0.5 * spec.mm_per_px)
