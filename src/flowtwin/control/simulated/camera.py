"""The twin's slip camera: frames rendered from the twin printer's motion, measured by vision.

:class:`TwinCameraSource` closes the simulated loop through real image processing: every
``interval_s`` it takes the twin's gear and filament speeds over the last
``(frames − 1)/fps`` seconds, renders those frames with the synthetic camera
(:class:`flowtwin.vision.synth.SyntheticCamera`: textured filament and toothed gear,
blur, noise) and measures them with the same OpenCV pipeline as a real camera
(:func:`flowtwin.vision.measure_frames`: Shi–Tomasi features, pyramidal Lucas–Kanade,
[003 §2.2]). The measured slip — not the twin's true one — goes to the controller.

Subsampling (documented, to keep a simulated print affordable): rendering a frame costs
~10–30 ms, so a burst of a few frames is filmed per measurement instead of a continuous
14.3 fps video [003 §2.1]; the controller averages over seconds anyway [003 §2.3]. While
the twin's gear is at rest over the whole burst (a heater wait), the camera would film a
still scene and the vision would flag the gear as stopped; the source then reports an
*idle* measurement without rendering. A burst is a slip measurement only over steady
forward feeding (:mod:`flowtwin.control.loop.burst`).
Each measurement also records the twin's true slip over the same frames
(:attr:`TwinCameraSource.records`), so the camera's error is known.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from flowtwin.control.loop.burst import IDLE_GEAR_SPEED_MM_S, measure_burst
from flowtwin.control.loop.measurement import Measurement
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.errors import ProfileError
from flowtwin.vision import Frame, VisionConfig
from flowtwin.vision.synth import MotionSeries, SceneSpec, SyntheticCamera
from flowtwin.vision.synth.motion import integrate_piecewise_linear

__all__ = ["CameraRecord", "TwinCameraSource", "twin_scene"]

#: Frame rate of Greeff's USB microscope, 1/s [003 §2.1: (70 ± 8) ms between frames].
GREEFF_FPS = 14.3


def twin_scene(filament_diameter_mm: float, *, fps: float = GREEFF_FPS,
               width_px: int = 640, height_px: int = 480, mm_per_px: float = 0.02,
               seed: int = 0) -> SceneSpec:
    """A synthetic-camera scene of Greeff's drive: 8 mm 24-tooth gear [003 §2.1].

    Parameters
    ----------
    filament_diameter_mm
        Nominal filament width in the image, mm.
    fps
        Frame rate, 1/s (default 14.3 [003 §2.1]).
    width_px, height_px, mm_per_px
        Frame size and scale (default 640×480 at ~20 µm/px [003 §2.1]).
    seed
        Seed of textures and noise.

    Returns
    -------
    SceneSpec
    """
    return SceneSpec(width_px=width_px, height_px=height_px, mm_per_px=mm_per_px, fps=fps,
                     filament_x_px=width_px * 430.0 / 640.0,
                     gear_center_y_px=height_px / 2.0,
                     nominal_width_mm=filament_diameter_mm, gear_tip_radius_mm=4.0,
                     gear_teeth=24, seed=seed)


@dataclass(frozen=True, slots=True)
class CameraRecord:
    """One measurement of the twin camera next to the twin's truth.

    Attributes
    ----------
    t_s
        Clock time of the last frame, s.
    measured_slip
        Slip from the vision pipeline (NaN if none).
    true_slip
        ``1 − ∫v_fil/∫v_gear`` of the twin over the same frames (NaN if the gear rests).
    measured_gear_speed_mm_s, true_gear_speed_mm_s
        Mean gear surface speed over the frames, measured and true, mm/s.
    idle
        The gear was at rest (nothing rendered).
    """

    t_s: float
    measured_slip: float
    true_slip: float
    measured_gear_speed_mm_s: float
    true_gear_speed_mm_s: float
    idle: bool


class TwinCameraSource:
    """A :class:`~flowtwin.control.loop.measurement.MeasurementSource` filming the twin printer.

    Parameters
    ----------
    twin
        The twin printer; it must have a print job.
    scene
        Synthetic-camera scene (default :func:`twin_scene` for the job's filament).
    config
        Vision configuration (default: ``scene.vision_config()`` — ROIs, scale, gear axis).
    frames
        Frames per measurement (>= 2; the first gives no speed).
    interval_s
        Clock time between measurements, s.
    seed
        Base seed: burst ``k`` renders with scene seed ``seed + k``.
    """

    def __init__(self, twin: TwinPrinter, *, scene: SceneSpec | None = None,
                 config: VisionConfig | None = None, frames: int = 4,
                 interval_s: float = 1.0, seed: int = 0) -> None:
        if twin.job is None:
            raise ProfileError("the twin camera needs a twin printer with a print job",
                               field="twin.job", allowed="TwinPrinter(job=JobRunner(...))")
        if frames < 2:
            raise ProfileError("a measurement needs at least two frames", field="frames",
                               value=frames, allowed=">= 2")
        if not (math.isfinite(interval_s) and interval_s > 0.0):
            raise ProfileError("measurement interval must be positive", field="interval_s",
                               value=interval_s, allowed="> 0 s")
        self.twin = twin
        self.scene = scene or twin_scene(twin.job.machine.filament.diameter_mm)
        self.config = config or self.scene.vision_config()
        self.frames = int(frames)
        self.interval_s = float(interval_s)
        self.seed = int(seed)
        self.span_s = (self.frames - 1) / self.scene.fps
        if self.span_s > self.interval_s:
            raise ProfileError("a burst lasts longer than the measurement interval",
                               field="interval_s", value=interval_s,
                               allowed=f">= (frames - 1)/fps = {self.span_s:.3f} s")
        #: Every measurement with the twin's truth beside it.
        self.records: list[CameraRecord] = []
        self._last: float | None = None
        self._bursts = 0
        self._idle = IDLE_GEAR_SPEED_MM_S

    def read(self) -> Measurement | None:
        """Film and measure a burst once per ``interval_s`` (None in between)."""
        clock = self.twin.clock
        now = clock.now()
        if self._last is not None and now - self._last < self.interval_s - 1e-9:
            return None
        runner = self.twin.job
        assert runner is not None
        t_a = now - self.span_s
        if t_a < runner.start_s:
            return None
        self._last = now
        self.twin.sync()
        t, gear, fil = runner.motion(t_a, now)
        t_rel = t - t_a
        g_dist = float(integrate_piecewise_linear(t_rel, gear, self.span_s))
        f_dist = float(integrate_piecewise_linear(t_rel, fil, self.span_s))
        true_slip = 1.0 - f_dist / g_dist if g_dist > self._idle * self.span_s \
            else math.nan
        if float(np.max(np.abs(gear))) <= self._idle:
            self.records.append(CameraRecord(now, math.nan, math.nan, 0.0, 0.0, True))
            return Measurement(now, math.nan, valid=False, idle=True, gear_speed_mm_s=0.0)
        width = np.full(t_rel.shape, self.scene.nominal_width_mm)
        motion = MotionSeries(t_rel, gear, fil, width)
        scene = replace(self.scene, seed=self.seed + self._bursts)
        self._bursts += 1
        camera = SyntheticCamera(scene, motion, duration_s=self.span_s)
        frames = [Frame(f.index, f.t_s, f.image) for f in camera.frames()]
        m, result = measure_burst(frames, self.config, t_s=now,
                                  frame_size=(scene.width_px, scene.height_px))
        self.records.append(CameraRecord(now, m.slip, true_slip,
                                         float(result.summary.gear_speed_mm_s),
                                         g_dist / self.span_s, m.idle))
        return m

    def close(self) -> None:
        """Nothing to release."""
