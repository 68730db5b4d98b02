"""Width accuracy per frame on the independent renderer (not a speed benchmark).

``python -m benchmarks.study_width [--seeds 1,2,3] [--held-out 7,8] [--frames 90]
[--codec mpeg4|ffv1] [--texture 1.0] [--out FILE]``

Renders clips with renderer 2 (``tests/vision/realcam.py``: knurled gear, textured white
filament with a specular stripe, lighting drift, motion blur, MPEG-4 part 2; gear
2 → 3.5 → 3 → 2 mm/s, slip 4 → 20 → 12 → 6 %, as ``tests/vision/test_realcam.py``), one
per seed, measures each through :func:`flowtwin.vision.measure` with the scale known
and two ``before`` ROIs (rows 20–120 and 130–170), and compares **every frame's** width
with the true mean width of the ROI's rows in that frame. Reported per clip: the median
error, the 95th percentile of ``|error|``, the worst frame, the frames beyond 0.5 px,
the refused (flagged, no width) frames and why, the clip's blur; and separately for the
development seeds (``--seeds``, 1–6: the ones the width model was tuned on) and the
held-out seeds (``--held-out``, 7, 8 and 11–14: looked at only after a change was
adopted): over the frames given a width, the median and 95th percentile of ``|error|``,
the worst frame and the count beyond 0.5 px, and the count of refused frames.

``--codec ffv1`` writes the same frames losslessly (FFV1) instead of MPEG-4 part 2, to
tell the compression's share of an error from the model's; ``--texture 0`` renders the
filament without its texture (the renderer's own switch), to tell the texture's share.

Not part of ``make bench`` (about 25 s per seed); figures go to docs/vision.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from tests.vision.realcam import (  # noqa: E402
    DriveProfile,
    RigCamera,
    RigSpec,
    render_clip,
    write_ffv1,
    write_mpeg4,
)

from flowtwin.vision import Roi, RoiSet, VisionConfig, measure  # noqa: E402

CODECS = ("mpeg4", "ffv1")


DRIVE = DriveProfile((0.0, 1.0, 2.0, 3.0), (2.0, 3.5, 3.0, 2.0), (0.04, 0.20, 0.12, 0.06))


def _rois(spec: RigSpec) -> dict[str, Roi]:
    cx, cy = spec.gear_center_px
    xl = spec.filament_x_px - spec.radius_px
    xr = spec.filament_x_px + spec.radius_px
    return {
        "face": Roi("gear", int(cx - 60), int(cy - 100), 120, 200),
        "before": Roi("before", int(xl - 20), 20, int(xr - xl + 40), 100),
        "before2": Roi("before", int(xl - 30), 130, int(xr - xl + 50), 40),
        "after": Roi("after", int(xl + 20), 330, int(xr - xl - 40), 140),
    }


def _total(errors: list[np.ndarray]) -> dict[str, object]:
    """Aggregate of per-frame errors (NaN: refused) over clips."""
    e = np.concatenate(errors) if errors else np.zeros(0)
    a = np.abs(e[np.isfinite(e)])
    return {"frames": int(e.size), "measured": int(a.size), "refused": int(e.size - a.size),
            "abs_median_px": float(np.median(a)) if a.size else None,
            "abs_p95_px": float(np.percentile(a, 95)) if a.size else None,
            "worst_px": float(a.max()) if a.size else None,
            "beyond_0p5": int(np.sum(a > 0.5))}


def _line(name: str, t: dict[str, object]) -> str:
    if not t["measured"]:
        return f"{name}: {t['frames']} frames, all refused"
    return (f"{name}: {t['frames']} frames, |err| median {t['abs_median_px']:.3f} px, p95 "
            f"{t['abs_p95_px']:.3f}, worst {t['worst_px']:.3f}, beyond 0.5 px "
            f"{t['beyond_0p5']}, refused {t['refused']}")


def study(seeds: list[int], n_frames: int, held_out: list[int] | None = None,
          codec: str = "mpeg4", texture: float = 1.0) -> dict[str, object]:
    """Per-frame width errors of every clip and ROI (see the module docstring)."""
    clips: dict[str, dict[str, object]] = {}
    errors: dict[int, list[np.ndarray]] = {}
    held = list(held_out or [])
    with tempfile.TemporaryDirectory() as tmp:
        for seed in [*seeds, *held]:
            spec = RigSpec(seed=seed, texture=texture)
            frames = render_clip(spec, DRIVE, n_frames)
            write = write_ffv1 if codec == "ffv1" else write_mpeg4
            path = write(frames, Path(tmp) / f"rig{seed}.avi", spec.fps)
            cam = RigCamera(spec, DRIVE)
            rois = _rois(spec)
            for name in ("before", "before2"):
                roi = rois[name]
                cfg = VisionConfig(rois=RoiSet(rois["face"], roi, rois["after"]),
                                   mm_per_px=spec.mm_per_px,
                                   diameter_mm=spec.filament_diameter_mm,
                                   gear_center_px=spec.gear_center_px,
                                   gear_radius_mm=spec.drive_radius_mm)
                res = measure(path, cfg)
                true = np.array([cam.true_width_mm(f.t_s, slice(roi.y, roi.y1))
                                 for f in frames]) / spec.mm_per_px
                err = np.asarray(res.series.width_px) - true
                ok = np.isfinite(err)
                a = np.abs(err[ok])
                clips[f"{seed}/{name}"] = {
                    "median_px": float(np.median(err[ok])) if ok.any() else None,
                    "abs_p95_px": float(np.percentile(a, 95)) if ok.any() else None,
                    "worst_px": float(a.max()) if ok.any() else None,
                    "beyond_0p5": int(np.sum(a > 0.5)), "refused": int(np.sum(~ok)),
                    "frames": int(err.size), "blur_px": res.summary.width_blur_px,
                    "note": res.summary.width_note,
                }
                errors.setdefault(seed, []).append(err)
                c = clips[f"{seed}/{name}"]
                if not ok.any():
                    print(f"seed {seed} {name:8s} refused in all {err.size} frames: "
                          f"{c['note']}", flush=True)
                    continue
                print(f"seed {seed} {name:8s} median {c['median_px']:+.3f} px, |err| p95 "
                      f"{c['abs_p95_px']:.3f}, worst {c['worst_px']:.3f}, beyond 0.5 px "
                      f"{c['beyond_0p5']}/{c['frames']}, refused {c['refused']}, blur "
                      f"{c['blur_px']:.3f} px", flush=True)
    dev = _total([e for sd in seeds for e in errors.get(sd, [])])
    out = _total([e for sd in held for e in errors.get(sd, [])])
    print(_line("development seeds " + ",".join(map(str, seeds)), dev))
    if held:
        print(_line("held-out seeds " + ",".join(map(str, held)), out))
    return {"clips": clips, "development": dev, "held_out": out}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--seeds", default="1,2,3,4,5,6")
    ap.add_argument("--held-out", default="7,8,11,12,13,14")
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--codec", choices=CODECS, default="mpeg4")
    ap.add_argument("--texture", type=float, default=1.0)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    held = [int(s) for s in args.held_out.split(",") if s]
    out = study([int(s) for s in args.seeds.split(",")], args.frames, held, args.codec,
                args.texture)
    if args.out:
        args.out.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
