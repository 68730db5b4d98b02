"""Vision benchmark: frames per second of the slip camera pipeline at 640×480.

Measured on synthetic frames (flowtwin.vision.synth) with OpenCV on one thread
(``cv2.setNumThreads(1)``):

* ``rois``: the pipeline with the three ROIs of docs/vision.md (gear rotation, filament
  translation, width), frames already in memory; wall-clock and CPU-time rates (the
  machine may be shared, CPU time is the fairer figure).
* ``file``: the same, reading an MJPG AVI through ``measure()`` (decoding included).
* ``full_frame``: gear and filament trackers on the whole 640×480 frame, and what that
  reads (static background features pull it towards zero).
* ``auto_axis``: the same ROIs without the gear axis: the first ``axis_frames`` frames
  also go through the axis estimate (flowtwin.vision.axis) before the pipeline; in
  memory and from the MJPG file (``file_auto_axis``: ``flowtwin vision measure`` as a
  user runs it on real footage, without ``--gear-center``).
* ``real_clip``: the real footage of [003] in tests/data/greeff2017 (281 frames, MPEG-4
  part 2, decoding included) with the ROIs of docs/vision.md's real-clip section.

The peer is [003 §2.1]: 14.3 frames/s (70 ms per frame) in Greeff and Schilling's set-up;
the goal is >= 150 frames/s (10×). Accuracy against the synthetic truth is printed too.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from flowtwin.vision import Frame, Roi, RoiSet, build_config, measure, measure_frames, parse_rois
from flowtwin.vision.synth import MotionSeries, SceneSpec, SyntheticCamera, write_video

PEER_FPS = 14.3          # [003 §2.1]: (70 ± 8) ms between frames
GOAL_FPS = 150.0
REAL_CLIP = (Path(__file__).resolve().parents[1] / "tests" / "data" / "greeff2017"
             / "greeff2017_rf1000_static.avi")


def _rate(fn, n_frames: int, repeats: int) -> tuple[float, float]:
    """Best wall-clock and CPU-time frames per second over ``repeats`` runs."""
    wall, cpu = [], []
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return n_frames / min(wall), n_frames / min(cpu)


def run(quick: bool = False) -> dict:
    """Measure and print; return the figures."""
    cv2.setNumThreads(1)
    n = 60 if quick else 240
    repeats = 2 if quick else 3
    out: dict = {"opencv": cv2.__version__, "frames": n, "threads": cv2.getNumThreads(),
                 "peer_fps_003": PEER_FPS, "goal_fps": GOAL_FPS}
    for speed in (2.0, 15.0):
        scene = SceneSpec(seed=21)
        motion = MotionSeries.constant(duration_s=(n - 1) / scene.fps, gear_speed_mm_s=speed,
                                       slip=0.1)
        synth = list(SyntheticCamera(scene, motion).frames())
        frames = [Frame(f.index, f.t_s, f.image) for f in synth]
        cfg = scene.vision_config()
        result = measure_frames(frames, cfg, frame_size=(640, 480))
        wall, cpu = _rate(lambda cfg=cfg, frames=frames: measure_frames(
            frames, cfg, frame_size=(640, 480)), n, repeats)
        s = result.summary
        key = f"{speed:g}mm_s"
        out[key] = {
            "rois_fps_wall": wall, "rois_fps_cpu": cpu,
            "ratio_vs_003": cpu / PEER_FPS,
            "gear_speed_err_pct": 100 * (s.gear_speed_mm_s / speed - 1),
            "filament_speed_err_pct": 100 * (s.filament_speed_mm_s / (0.9 * speed) - 1),
            "slip_err_pp": 100 * (s.slip - 0.1),
            "width_err_um": 1000 * (s.width_mm - float(np.mean([f.width_mm for f in synth]))),
            "valid_frames": s.valid_frames, "frame_count": s.frames,
        }
        # end to end from a real file (MJPG decode + pipeline), the axis given and
        # estimated (`flowtwin vision measure` without --gear-center)
        auto_cfg = dataclasses.replace(cfg, gear_center_px=None, gear_radius_mm=None)
        with tempfile.TemporaryDirectory() as tmp:
            path = write_video(synth, Path(tmp) / "bench.avi", fps=scene.fps, fourcc="MJPG")
            f_wall, f_cpu = _rate(lambda path=path, cfg=cfg: measure(path, cfg), n, repeats)
            fa_wall, fa_cpu = _rate(lambda path=path, c=auto_cfg: measure(path, c), n,
                                    repeats)
        out[key]["file_fps_wall"], out[key]["file_fps_cpu"] = f_wall, f_cpu
        out[key]["file_auto_axis_fps_wall"] = fa_wall
        out[key]["file_auto_axis_fps_cpu"] = fa_cpu
        # full frame: both trackers over the whole image
        full = Roi("after", 0, 0, 640, 480)
        full_cfg = dataclasses.replace(cfg, rois=RoiSet(
            Roi("gear", 0, 0, 640, 480), cfg.rois.before, full))
        full_res = measure_frames(frames, full_cfg, frame_size=(640, 480))
        ff_wall, ff_cpu = _rate(lambda c=full_cfg, frames=frames: measure_frames(
            frames, c, frame_size=(640, 480)), n, repeats)
        fs = full_res.summary
        out[key].update({
            "full_frame_fps_wall": ff_wall, "full_frame_fps_cpu": ff_cpu,
            "full_frame_filament_err_pct": 100 * (fs.filament_speed_mm_s / (0.9 * speed) - 1),
            "full_frame_valid_frames": fs.filament_valid_frames,
        })
        # the gear axis estimated from the motion (no --gear-center)
        auto_res = measure_frames(frames, auto_cfg, frame_size=(640, 480))
        a_wall, a_cpu = _rate(lambda c=auto_cfg, frames=frames: measure_frames(
            frames, c, frame_size=(640, 480)), n, repeats)
        a_s = auto_res.summary
        out[key].update({
            "auto_axis_fps_wall": a_wall, "auto_axis_fps_cpu": a_cpu,
            "auto_axis_mode": a_s.gear_mode,
            "auto_axis_gear_err_pct": 100 * (a_s.gear_speed_mm_s / speed - 1),
        })
    if REAL_CLIP.is_file():
        real_cfg = build_config(rois=parse_rois(["gear=311,167,40,40", "after=334,364,40,40",
                                                 "before=320,20,190,100"]), mm_per_px=0.0206)
        r_wall, r_cpu = _rate(lambda: measure(REAL_CLIP, real_cfg), 281, repeats)
        rs = measure(REAL_CLIP, real_cfg).summary
        out["real_clip"] = {"fps_wall": r_wall, "fps_cpu": r_cpu, "frames": 281,
                            "width_mm": rs.width_mm, "slip": rs.slip,
                            "gear_state": rs.gear_state}
    print(f"OpenCV {out['opencv']}, {out['threads']} thread, {n} frames of 640×480, "
          f"peer [003] {PEER_FPS} fps, goal {GOAL_FPS:.0f} fps")
    print(f"{'speed':>8} {'ROIs fps (cpu/wall)':>21} {'x[003]':>7} {'file fps':>10} "
          f"{'full fps':>9} {'gear err':>9} {'fil err':>8} {'slip err':>9} "
          f"{'width err':>10} {'full-frame fil err':>19}")
    for speed in (2.0, 15.0):
        r = out[f"{speed:g}mm_s"]
        full = r["full_frame_filament_err_pct"]
        full_text = "all flagged" if math.isnan(full) else f"{full:+.1f}%"
        print(f"{speed:>5g} mm/s {r['rois_fps_cpu']:>9.0f} / {r['rois_fps_wall']:<9.0f}"
              f"{r['ratio_vs_003']:>7.1f} {r['file_fps_cpu']:>10.0f} "
              f"{r['full_frame_fps_cpu']:>9.0f} {r['gear_speed_err_pct']:>+8.3f}% "
              f"{r['filament_speed_err_pct']:>+7.3f}% {r['slip_err_pp']:>+7.3f}pp "
              f"{r['width_err_um']:>+8.2f}µm {full_text:>18}")
    for speed in (2.0, 15.0):
        r = out[f"{speed:g}mm_s"]
        print(f"{speed:>5g} mm/s, axis estimated: {r['auto_axis_fps_cpu']:.0f} fps (cpu), "
              f"from the MJPG file {r['file_auto_axis_fps_cpu']:.0f} fps (cpu), "
              f"{r['auto_axis_mode']} mode, gear {r['auto_axis_gear_err_pct']:+.3f}%")
    if "real_clip" in out:
        rc = out["real_clip"]
        print(f"real clip [003] (MPEG-4 decode included): {rc['fps_cpu']:.0f} fps (cpu) / "
              f"{rc['fps_wall']:.0f} (wall), width {rc['width_mm']:.4f} mm, gear "
              f"{rc['gear_state']}")
    out["goal_met"] = all(out[f"{v:g}mm_s"]["rois_fps_cpu"] >= GOAL_FPS for v in (2.0, 15.0))
    print(f"goal >= {GOAL_FPS:.0f} fps (CPU time, ROIs, frames in memory): "
          f"{'met' if out['goal_met'] else 'NOT met'}")
    return out


if __name__ == "__main__":
    run()
