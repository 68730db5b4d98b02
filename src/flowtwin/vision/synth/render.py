"""Render the frames a slip camera would record from a known motion (ground truth).

Each frame is composed physically: a static background and pinch bearing, the filament
(a band-limited texture fixed to the material, shifted by the exact fed length with an
8-tap Lanczos kernel, so sub-pixel motion is rendered without interpolation bias; edges
are anti-aliased analytically at the local width), then the toothed gear rotated by the
exact angle (cubic resampling of a 2× supersampled gear), motion blur over the exposure,
an illumination gain, optical blur and read + shot noise, quantised to 8 bits.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.vision.roi import Roi
from flowtwin.vision.synth.motion import MotionSeries
from flowtwin.vision.synth.scene import SceneSpec

__all__ = ["SyntheticCamera", "SyntheticFrame", "render_from_series"]

F32 = npt.NDArray[np.float32]
FrameKind = Literal["normal", "blank", "duplicate"]


@dataclass(frozen=True, slots=True)
class SyntheticFrame:
    """One delivered frame and the truth behind it.

    Attributes
    ----------
    index
        Capture index (dropped frames leave gaps), 0-based.
    t_s
        Capture time (the timestamp a camera would report), s.
    image
        Grey image, shape ``(H, W)``, uint8.
    gear_distance_mm
        Arc length of the gear surface at the drive radius since ``t = 0``, mm.
    gear_angle_rad
        Gear angle since ``t = 0`` (positive drives the filament down), rad.
    filament_distance_mm
        Filament fed since ``t = 0``, mm.
    width_mm
        Mean true width over the rows of the ``before`` ROI, mm.
    kind
        ``"normal"``, ``"blank"`` or ``"duplicate"`` (repeat of the previous image).
    """

    index: int
    t_s: float
    image: npt.NDArray[np.uint8]
    gear_distance_mm: float
    gear_angle_rad: float
    filament_distance_mm: float
    width_mm: float
    kind: FrameKind


def _bandlimited_noise(shape: tuple[int, int], sigma_px: float,
                       rng: np.random.Generator) -> npt.NDArray[np.float64]:
    """Periodic white noise low-passed by a Gaussian of ``sigma_px``, unit rms."""
    white = rng.standard_normal(shape)
    fy = np.fft.fftfreq(shape[0])[:, None]
    fx = np.fft.rfftfreq(shape[1])[None, :]
    transfer = np.exp(-2.0 * (math.pi * sigma_px) ** 2 * (fx * fx + fy * fy))
    out = np.fft.irfft2(np.fft.rfft2(white) * transfer, s=shape)
    return out / out.std()


def _lanczos_taps(frac: float) -> F32:
    """8 Lanczos-4 weights for offsets ``-3..4`` that shift a signal by ``frac`` px."""
    x = np.arange(-3, 5, dtype=np.float64) - frac
    w = np.sinc(x) * np.sinc(x / 4.0)
    return (w / w.sum()).astype(np.float32)


class SyntheticCamera:
    """A camera looking at a filament drive whose motion is known exactly.

    Parameters
    ----------
    scene
        Geometry, appearance and defects.
    motion
        Gear speed, filament speed and width over time.
    width_roi
        ROI over which the true width is averaged (default: the scene's ``before`` ROI).
    duration_s
        Length of the recording (default: the motion's last time), s.
    """

    def __init__(self, scene: SceneSpec, motion: MotionSeries, *,
                 width_roi: Roi | None = None, duration_s: float | None = None) -> None:
        self.scene = scene
        self.motion = motion
        self.width_roi = width_roi or scene.suggested_rois().before
        end = float(motion.t_s[-1]) if duration_s is None else float(duration_s)
        n = max(1, int(math.floor(end * scene.fps + 1e-9)) + 1)
        rng = np.random.default_rng(scene.seed)
        t = np.arange(n) / scene.fps
        if scene.timestamp_jitter_s > 0:
            t = t + rng.normal(0.0, scene.timestamp_jitter_s, n)
            t = np.maximum.accumulate(t + np.arange(n) * 1e-6)
        self.capture_times_s = t
        self._rng_noise = np.random.default_rng(rng.integers(2**63))
        self._px = scene.mm_per_px
        self._build_background(rng)
        self._build_filament(rng)
        self._build_gear(rng)
        self._build_width_lookup()

    # --- static parts -------------------------------------------------------------
    def _build_background(self, rng: np.random.Generator) -> None:
        sc = self.scene
        h, w = sc.height_px, sc.width_px
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        bg = sc.background_dn * (1.0 + 0.15 * np.sin(xx / 97.0 + 0.4) * np.cos(yy / 131.0))
        bg = bg + 6.0 * _bandlimited_noise((h, w), 2.5, rng)
        bx, by = sc.bearing_center_px
        r_b = sc.bearing_radius_mm / self._px
        rr = np.hypot(xx - bx, yy - by)
        cover = np.clip(r_b - rr + 0.5, 0.0, 1.0)
        shade = 150.0 - 40.0 * np.clip(rr / r_b, 0.0, 1.0) ** 2
        self._background = (bg * (1.0 - cover) + shade * cover).astype(np.float32)

    def _build_filament(self, rng: np.random.Generator) -> None:
        sc, px = self.scene, self._px
        half = 0.5 * sc.nominal_width_mm / px + (sc.width_variation_mm + 0.3) / px + 6.0
        self._sx0 = max(0, int(math.floor(sc.filament_x_px - half)))
        self._sx1 = min(sc.width_px, int(math.ceil(sc.filament_x_px + half)) + 1)
        wt = self._sx1 - self._sx0
        d_max = float(np.max(np.abs(self.motion.filament_distance_mm(self.capture_times_s))))
        span = d_max / px + sc.height_px + 64
        period = 1 << max(10, math.ceil(math.log2(span)))
        self._period = period
        tex = 0.75 * _bandlimited_noise((period, wt), 1.6, rng)
        tex += 0.5 * _bandlimited_noise((period, wt), 5.0, rng)
        tex /= tex.std()
        # texture contrast along the material (gaps), material row m = row index mod P
        m_mm = np.arange(period) * px
        contrast = np.full(period, 0.12 * sc.filament_texture)
        for m0, m1 in sc.texture_gaps_mm:
            for shift in (-period * px, 0.0, period * px):
                inside = (m_mm >= m0 + shift) & (m_mm <= m1 + shift)
                contrast[inside] = 0.12 * sc.gap_texture
        tex *= contrast[:, None]
        # bite marks of the teeth on the gear side: one dent per tooth pitch
        pitch = 2.0 * math.pi * sc.drive_radius_mm / sc.gear_teeth / px
        pitch = period / max(1, round(period / pitch))   # whole pitches per period: no seam
        rows = np.arange(period, dtype=np.float64)[:, None]
        cols = np.arange(wt, dtype=np.float64)[None, :] + self._sx0
        phase = np.mod(rows, pitch)
        dist = np.minimum(phase, pitch - phase)
        dent = np.exp(-0.5 * (dist / 5.0) ** 2) * np.exp(
            -0.5 * ((cols - sc.filament_left_px - 3.0) / 4.0) ** 2)
        self._tile = np.concatenate([tex, dent], axis=1).astype(np.float32)
        self._wt = wt
        yy = np.arange(sc.height_px, dtype=np.float32)[:, None]
        r_tip = sc.gear_tip_radius_mm / px
        contact_half = math.sqrt(max(r_tip ** 2 - (sc.filament_left_px
                                                   - sc.gear_center_px[0]) ** 2, 0.0))
        self._after_mask = np.clip((yy - sc.gear_center_y_px) / max(contact_half, 1.0), 0, 1)

    def _build_gear(self, rng: np.random.Generator) -> None:
        sc, px = self.scene, self._px
        r_tip = sc.gear_tip_radius_mm / px
        r_root = (sc.gear_tip_radius_mm - sc.tooth_depth_mm) / px
        size = 2 * math.ceil(r_tip + 4) + 1
        c = (size - 1) / 2.0
        self._gear_size, self._gear_c, self._r_tip = size, c, r_tip
        # outline at 2x supersampling, area-averaged: anti-aliased alpha
        ss = 2
        g = (np.arange(size * ss, dtype=np.float64) + 0.5) / ss - 0.5 - c
        yy, xx = np.meshgrid(g, g, indexing="ij")
        r = np.hypot(xx, yy)
        u = np.mod(np.arctan2(yy, xx) * sc.gear_teeth / (2 * math.pi), 1.0)
        prof = np.interp(u, [0.0, 0.35, 0.5, 0.85, 1.0], [1.0, 1.0, 0.0, 0.0, 1.0])
        inside = (r <= r_root + (r_tip - r_root) * prof).astype(np.float32)
        alpha = cv2.resize(inside, (size, size), interpolation=cv2.INTER_AREA)
        # face: turned rings, random texture, brighter hobbed teeth, textured shaft with a flat
        g1 = np.arange(size, dtype=np.float64) - c
        yy, xx = np.meshgrid(g1, g1, indexing="ij")
        r = np.hypot(xx, yy)
        face = 125.0 + 18.0 * sc.gear_rings * np.cos(2 * math.pi * r / 7.0)
        face += 22.0 * sc.gear_face_texture * _bandlimited_noise((size, size), 1.5, rng)
        face += 25.0 * np.clip((r - r_root + 3.0) / 3.0, 0.0, 1.0)
        r_shaft = 2.5 / px
        shaft = np.clip(r_shaft - r + 0.5, 0.0, 1.0) * np.clip(xx - (-0.8 * r_shaft) + 0.5, 0, 1)
        shaft_img = 95.0 + 14.0 * sc.gear_face_texture * _bandlimited_noise((size, size), 2.0,
                                                                        rng)
        face = face * (1.0 - shaft) + shaft_img * shaft
        gear = cv2.GaussianBlur(face.astype(np.float32), (0, 0), 0.6)
        # premultiplied grey and alpha in one 2-channel image: one warp per angle
        self._gear_pm = np.ascontiguousarray(np.dstack([gear * alpha, alpha]),
                                             dtype=np.float32)

    def _build_width_lookup(self) -> None:
        """Width of the material as a function of its coordinate ``m`` (mm)."""
        sc, mo = self.scene, self.motion
        self._w_const = bool(np.all(mo.width_mm == mo.width_mm[0]))
        y_ref = self.width_roi.center[1] * self._px
        t_grid = np.linspace(float(mo.t_s[0]), float(max(mo.t_s[-1],
                             self.capture_times_s[-1])), 4001)
        s_grid = np.maximum.accumulate(mo.filament_distance_mm(t_grid))
        # material m passes the reference row when s(t*) = y_ref - m
        self._m_table = y_ref - s_grid[::-1]
        self._w_table = mo.width_at(t_grid)[::-1]
        self._phase_w = float(np.random.default_rng(sc.seed + 1).uniform(0, 2 * math.pi))

    def width_of_material(self, m_mm: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """True width of the material at coordinate ``m_mm`` (mm), mm."""
        sc = self.scene
        m = np.asarray(m_mm, dtype=np.float64)
        if self._w_const:
            base = np.full(m.shape, float(self.motion.width_mm[0]))
        else:
            base = np.interp(m, self._m_table, self._w_table)
        return base + sc.width_variation_mm * np.sin(
            2 * math.pi * m / sc.width_wavelength_mm + self._phase_w)

    # --- per frame -----------------------------------------------------------------
    def _filament_layer(self, s_px: npt.NDArray[np.float64], widths_px: npt.NDArray[np.float64]
                        ) -> tuple[F32, F32]:
        """Texture rows shifted by the fed length; ``s_px`` are the exposure sub-samples."""
        sc = self.scene
        kernel: dict[int, float] = {}
        for s in s_px:
            base = math.floor(-s)
            taps = _lanczos_taps(-s - base)
            for j, wgt in zip(range(-3, 5), taps, strict=True):
                kernel[base + j] = kernel.get(base + j, 0.0) + float(wgt) / len(s_px)
        rows = np.arange(sc.height_px)
        acc = np.zeros((sc.height_px, self._tile.shape[1]), dtype=np.float32)
        for off, wgt in kernel.items():
            acc += np.float32(wgt) * self._tile[(rows + off) % self._period]
        tex, dent = acc[:, :self._wt], acc[:, self._wt:]
        x = np.arange(self._sx0, self._sx1, dtype=np.float32)[None, :]
        xc = np.float32(sc.filament_x_px)
        half = (0.5 * widths_px).astype(np.float32)[:, None]
        xl, xr = xc - half, xc + half
        cover = np.clip(x + 0.5 - xl, 0, 1) * np.clip(xr - x + 0.5, 0, 1)
        u = np.clip((x - xc) / half, -1.0, 1.0)
        shade = (1.0 - sc.shading) + sc.shading * np.sqrt(1.0 - u * u)
        bright = sc.filament_dn * shade * (1.0 - 0.35 * dent * self._after_mask)
        fil = bright * (1.0 + tex)
        if sc.glossy > 0:
            gx = xc - 0.22 * 2 * half
            fil = fil + 70.0 * sc.glossy * np.exp(-0.5 * ((x - gx) / (0.12 * half)) ** 2)
        return fil.astype(np.float32), cover.astype(np.float32)

    def _gear_layer(self, angles: npt.NDArray[np.float64]) -> tuple[tuple[int, int, int, int],
                                                                     F32, F32]:
        sc = self.scene
        cx, cy = sc.gear_center_px
        r = self._r_tip + 3
        x0, y0 = max(0, math.floor(cx - r)), max(0, math.floor(cy - r))
        x1, y1 = min(sc.width_px, math.ceil(cx + r) + 1), min(sc.height_px, math.ceil(cy + r) + 1)
        acc = np.zeros((y1 - y0, x1 - x0, 2), np.float32)
        for th in angles:
            co, si = math.cos(th), math.sin(th)
            # destination (X, Y) -> gear-local q = c + R(-th)((X + x0, Y + y0) - centre)
            dx, dy = x0 - cx, y0 - cy
            m = np.array([[co, si, self._gear_c + co * dx + si * dy],
                          [-si, co, self._gear_c - si * dx + co * dy]], dtype=np.float64)
            flags = cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP
            acc += cv2.warpAffine(self._gear_pm, m, (x1 - x0, y1 - y0), flags=flags,
                                  borderMode=cv2.BORDER_CONSTANT)
        n = np.float32(len(angles))
        return (x0, y0, x1, y1), acc[:, :, 0] / n, np.clip(acc[:, :, 1] / n, 0.0, 1.0)

    def _render(self, t: float) -> tuple[npt.NDArray[np.uint8], float, float, float]:
        sc, px, mo = self.scene, self._px, self.motion
        r_drive = sc.drive_radius_mm
        # exposure sub-samples for motion blur: filament one per ~0.5 px of motion (at most 8),
        # gear one per ~1.5 px at the tips (at most 3: each is a warp of the whole gear)
        te = sc.exposure_s
        span_f = abs(float(mo.filament_distance_mm(t + te / 2) - mo.filament_distance_mm(
            t - te / 2))) / px
        span_g = abs(float(mo.gear_distance_mm(t + te / 2) - mo.gear_distance_mm(
            t - te / 2))) / r_drive * self._r_tip
        n_f = int(min(8, max(1, math.ceil(span_f / 0.5))))
        n_g = int(min(3, max(1, math.ceil(span_g / 1.5))))
        tf = t + te * ((np.arange(n_f) + 0.5) / n_f - 0.5) if n_f > 1 else np.array([t])
        tg = t + te * ((np.arange(n_g) + 0.5) / n_g - 0.5) if n_g > 1 else np.array([t])
        s_mm = float(mo.filament_distance_mm(t))
        g_mm = float(mo.gear_distance_mm(t))
        rows = np.arange(sc.height_px, dtype=np.float64)
        widths_mm = self.width_of_material(rows * px - s_mm)
        frame = self._background.copy()
        fil, cover = self._filament_layer(mo.filament_distance_mm(tf) / px, widths_mm / px)
        strip = frame[:, self._sx0:self._sx1]
        strip *= 1.0 - cover
        strip += fil * cover
        (x0, y0, x1, y1), gimg, galpha = self._gear_layer(mo.gear_distance_mm(tg) / r_drive)
        sub = frame[y0:y1, x0:x1]
        sub *= 1.0 - galpha
        sub += gimg
        gain = 1.0 + sc.gain_amplitude * math.sin(2 * math.pi * t / sc.gain_period_s)
        frame *= np.float32(gain)
        if sc.blur_px > 0:
            frame = cv2.GaussianBlur(frame, (0, 0), sc.blur_px)
        frame = self._noise(frame)
        roi = self.width_roi
        w_true = float(np.mean(widths_mm[roi.y:roi.y1]))
        return frame, g_mm, s_mm, w_true

    def _noise(self, frame: F32) -> npt.NDArray[np.uint8]:
        sc = self.scene
        if sc.noise_dn > 0 or sc.shot_noise:
            sigma = np.sqrt(np.float32(sc.noise_dn ** 2) + np.maximum(frame, 0) / 8.0) \
                if sc.shot_noise else np.float32(sc.noise_dn)
            frame = frame + sigma * self._rng_noise.standard_normal(frame.shape,
                                                                    dtype=np.float32)
        return np.clip(np.rint(frame), 0, 255).astype(np.uint8)

    def frames(self) -> Iterator[SyntheticFrame]:
        """Render the recording frame by frame (dropped frames are skipped)."""
        sc = self.scene
        dropped, blank, dup = set(sc.dropped_frames), set(sc.blank_frames), \
            set(sc.duplicate_frames)
        previous: SyntheticFrame | None = None
        for i, t in enumerate(self.capture_times_s):
            if i in dropped:
                continue
            t = float(t)
            if i in dup and previous is not None:
                previous = SyntheticFrame(i, t, previous.image, previous.gear_distance_mm,
                                          previous.gear_angle_rad,
                                          previous.filament_distance_mm, previous.width_mm,
                                          "duplicate")
                yield previous
                continue
            if i in blank:
                h, w = sc.height_px, sc.width_px
                img = self._noise(np.full((h, w), 2.0, np.float32))
                g_mm = float(self.motion.gear_distance_mm(t))
                s_mm = float(self.motion.filament_distance_mm(t))
                yield SyntheticFrame(i, t, img, g_mm, g_mm / sc.drive_radius_mm, s_mm,
                                     math.nan, "blank")
                continue
            img, g_mm, s_mm, w_true = self._render(t)
            previous = SyntheticFrame(i, t, img, g_mm, g_mm / sc.drive_radius_mm, s_mm,
                                      w_true, "normal")
            yield previous


def render_from_series(t_s: npt.ArrayLike, gear_speed_mm_s: npt.ArrayLike,
                       filament_speed_mm_s: npt.ArrayLike, width_mm: npt.ArrayLike, *,
                       scene: SceneSpec | None = None) -> list[SyntheticFrame]:
    """Render what the camera would record for a given time series (e.g. from the twin).

    Parameters
    ----------
    t_s
        Strictly increasing sample times, shape ``(K,)``, s; the recording covers
        ``[t_s[0], t_s[-1]]`` at ``scene.fps`` (so ``t_s[0]`` should be 0).
    gear_speed_mm_s
        Gear surface speed ``ω·R`` at the drive radius, shape ``(K,)``, mm/s.
    filament_speed_mm_s
        Filament transport speed, shape ``(K,)``, mm/s.
    width_mm
        Width of the filament passing the camera, shape ``(K,)``, mm.
    scene
        Scene (default :class:`SceneSpec()`).

    Returns
    -------
    list of SyntheticFrame
        The delivered frames with their ground truth.
    """
    motion = MotionSeries(np.asarray(t_s, dtype=np.float64),
                          np.asarray(gear_speed_mm_s, dtype=np.float64),
                          np.asarray(filament_speed_mm_s, dtype=np.float64),
                          np.asarray(width_mm, dtype=np.float64))
    return list(SyntheticCamera(scene or SceneSpec(), motion).frames())
