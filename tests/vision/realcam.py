"""A second synthetic slip camera, written apart from :mod:`flowtwin.vision.synth`.

It renders the kind of scene in the real clip of [003] (tests/data/greeff2017): a colour
microscope view of a knurled 24-tooth drive gear on the left, a white filament with a
specular highlight and teeth marks in the middle, a dark glossy idler bearing on the
right, a blue cloth behind — and it renders it by another method than the project's
renderer, so that the two do not share blind spots:

* **No image resampling.** Everything is evaluated from analytic or procedural functions
  at sample points: the filament texture is a sum of plane waves fixed to the material,
  and the gear's face texture a sum of angular harmonics fixed to the gear. The project's
  renderer shifts a texture image with a Lanczos kernel and rotates a supersampled gear
  image with cubic interpolation.
* **Exact pixel area and motion blur for textures.** A plane wave ``cos(2πf·m)`` averaged
  over a pixel's height and over the distance travelled during the exposure is the same
  wave times ``sinc(f·k)·sinc(f·v·τ)``; an angular harmonic ``cos(n·φ)`` averaged over the
  angle swept is times ``sinc(n·ω·τ/2π)``. Both are applied per term. Across the
  filament, 8 sub-columns per pixel integrate the cylinder's shading and silhouette.
* **The gear outline** (knurl teeth) is sampled 2×2 per pixel at 4 instants of the
  exposure, the filament behind it shows through the tooth gaps.
* **Colour, lighting drift, noise, compression.** Scene colours in BGR, a global and a
  spatial gain that drift slowly, optical blur, shot and read noise, 8-bit quantisation,
  and the frames are written with ``cv2.VideoWriter`` as MPEG-4 part 2 (the real clip's
  codec) and decoded again by the pipeline.
* **Slip that varies in time**: the gear surface speed and the slip are piecewise linear
  in time; positions are integrated on a 0.1 ms grid (trapezoids).

Ground truth per frame: the gear surface distance at the drive radius, the filament
distance and the true mean width over any rows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

_SUB_X = 8            # sub-columns per pixel across the filament
_GEAR_SUB = 2         # gear outline: 2×2 samples per pixel
_GEAR_TIMES = 4       # gear outline: instants per exposure


def _sinc(x: F64) -> F64:
    return np.sinc(x)            # sin(πx)/(πx)


@dataclass(frozen=True)
class DriveProfile:
    """Gear surface speed and slip, piecewise linear in time (knots ``t_s``)."""

    t_s: tuple[float, ...]
    gear_speed_mm_s: tuple[float, ...]
    slip: tuple[float, ...]

    def speeds(self, t: F64) -> tuple[F64, F64]:
        """Gear surface speed and filament speed at times ``t``, mm/s."""
        g = np.interp(t, self.t_s, self.gear_speed_mm_s)
        s = np.interp(t, self.t_s, self.slip)
        return g, g * (1.0 - s)

    def distances(self, t: F64) -> tuple[F64, F64]:
        """Gear surface distance and filament distance since ``t = 0``, mm (trapezoids on
        a 0.1 ms grid, exact for the piecewise linear speeds up to the grid's rounding)."""
        end = max(float(np.max(t)), self.t_s[-1]) + 1e-3
        grid = np.arange(0.0, end + 1e-4, 1e-4)
        g, f = self.speeds(grid)
        cg = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(grid))])
        cf = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(grid))])
        return np.interp(t, grid, cg), np.interp(t, grid, cf)


@dataclass(frozen=True)
class RigSpec:
    """Geometry and appearance of the rig (defaults: like the real clip, 18.5 µm/px)."""

    width_px: int = 640
    height_px: int = 480
    mm_per_px: float = 0.0185
    fps: float = 30.0
    exposure_s: float = 0.008
    filament_diameter_mm: float = 2.85
    width_wave_mm: float = 0.015          # amplitude of the diameter's variation
    width_wavelength_mm: float = 6.0
    filament_x_px: float = 400.0          # column of the filament axis
    contact_y_px: float = 262.0           # row of the gear axis (the contact)
    gear_tip_mm: float = 4.0
    gear_teeth: int = 24
    tooth_depth_mm: float = 0.3
    bite_mm: float = 0.1                  # drive radius = tip − bite
    bearing_radius_mm: float = 5.0
    highlight_u: float = 0.28             # specular stripe across the filament (−1..1)
    highlight: float = 120.0              # its peak, DN before gain (saturates)
    teeth_marks: bool = True
    mark_depth_mm: float = 0.05
    texture: float = 1.0                  # filament texture contrast factor
    gear_texture: float = 1.0
    drift: float = 0.10                   # lighting drift amplitude (fraction)
    blur_px: float = 1.2
    read_noise_dn: float = 1.5
    shot_noise: bool = True
    seed: int = 1

    @property
    def radius_px(self) -> float:
        return 0.5 * self.filament_diameter_mm / self.mm_per_px

    @property
    def drive_radius_mm(self) -> float:
        return self.gear_tip_mm - self.bite_mm

    @property
    def gear_center_px(self) -> tuple[float, float]:
        left = self.filament_x_px - self.radius_px
        return left - self.drive_radius_mm / self.mm_per_px, self.contact_y_px

    @property
    def bearing_center_px(self) -> tuple[float, float]:
        right = self.filament_x_px + self.radius_px
        return right + self.bearing_radius_mm / self.mm_per_px, self.contact_y_px


@dataclass
class RigFrame:
    """One rendered frame (BGR) and its truth."""

    index: int
    t_s: float
    bgr: npt.NDArray[np.uint8]
    gear_distance_mm: float
    filament_distance_mm: float
    gear_speed_mm_s: float
    filament_speed_mm_s: float
    material_shift_mm: float = field(repr=False, default=0.0)


class RigCamera:
    """Renders :class:`RigFrame` s of a :class:`RigSpec` driven by a :class:`DriveProfile`."""

    def __init__(self, spec: RigSpec, drive: DriveProfile) -> None:
        self.spec = spec
        self.drive = drive
        self.rng = np.random.default_rng(spec.seed)
        h, w = spec.height_px, spec.width_px
        self.y = np.arange(h, dtype=np.float64)
        self.x = np.arange(w, dtype=np.float64)
        self._table: tuple[F64, F64, F64] | None = None
        self._background()
        self._filament_setup()
        self._gear_setup()

    # --- static scene -----------------------------------------------------------------
    def _background(self) -> None:
        s, rng = self.spec, self.rng
        h, w = s.height_px, s.width_px
        # blue cloth: low-frequency blotches (sum of a few random waves per channel)
        yy, xx = np.meshgrid(self.y, self.x, indexing="ij")
        blot = np.zeros((h, w))
        for _ in range(12):
            fx, fy = rng.normal(0, 0.012, 2)
            blot += rng.normal(0, 0.12) * np.cos(2 * np.pi * (fx * xx + fy * yy)
                                                 + rng.uniform(0, 2 * np.pi))
        base = np.array([150.0, 28.0, 12.0])                      # B, G, R: grey ≈ 37
        bg = base[None, None, :] * (1.0 + blot[:, :, None])
        # idler bearing: dark glossy disc, a bright rim glint, static
        bx, by = s.bearing_center_px
        rb = s.bearing_radius_mm / s.mm_per_px
        d = np.hypot(xx - bx, yy - by)
        cover = np.clip(rb - d + 0.5, 0.0, 1.0)
        shade = 18.0 + 10.0 * np.cos(np.arctan2(yy - by, xx - bx) * 3.0) ** 2
        glint = 150.0 * np.exp(-(((d - (rb - 9.0)) / 2.0) ** 2)) * (
            0.6 + 0.4 * np.cos(np.arctan2(yy - by, xx - bx) * 7.0))
        bearing = (shade + glint)[:, :, None] * np.array([1.0, 1.02, 1.05])[None, None, :]
        self.bg = (bg * (1.0 - cover[:, :, None]) + bearing * cover[:, :, None]
                   ).astype(np.float32)

    def _filament_setup(self) -> None:
        s, rng = self.spec, self.rng
        r = s.radius_px
        x0 = int(math.floor(s.filament_x_px - r - 4))
        x1 = int(math.ceil(s.filament_x_px + r + 4))
        self.fx0, self.fx1 = x0, x1
        sub = (np.arange(_SUB_X) + 0.5) / _SUB_X - 0.5
        self.fxs = (np.arange(x0, x1)[:, None] + sub[None, :]).ravel()      # sub-columns
        u = np.clip((self.fxs - s.filament_x_px) / r, -1.0, 1.0)
        arc_mm = np.arcsin(u) * 0.5 * s.filament_diameter_mm               # across surface
        n = 90
        # plane waves on the surface: spatial frequency up to ~1/(3 px)
        fmax = 1.0 / (3.0 * s.mm_per_px)
        mag = fmax * np.sqrt(rng.uniform(0.0, 1.0, n))
        ang = rng.uniform(0.0, np.pi, n)
        self.tf_m = mag * np.cos(ang)                                      # cycles/mm along
        self.tf_a = mag * np.sin(ang)                                      # cycles/mm across
        self.t_amp = s.texture * 0.11 * rng.normal(0.0, 1.0, n) / math.sqrt(n) * 2.0
        self.t_phase = rng.uniform(0.0, 2 * np.pi, n)
        a = 2 * np.pi * self.tf_a[None, :] * arc_mm[:, None]
        self.t_cos_a = np.cos(a).T.astype(np.float32)                      # (n, cols)
        self.t_sin_a = np.sin(a).T.astype(np.float32)
        self.width_phase = rng.uniform(0, 2 * np.pi)
        self.mark_phase = rng.uniform(0.0, 1.0)
        albedo = np.array([200.0, 208.0, 214.0])
        self.fil_albedo = albedo

    def _gear_setup(self) -> None:
        s, rng = self.spec, self.rng
        cx, cy = s.gear_center_px
        k = s.mm_per_px
        self.r_tip = s.gear_tip_mm / k
        self.r_root = (s.gear_tip_mm - s.tooth_depth_mm) / k
        x1 = min(s.width_px, int(math.ceil(cx + self.r_tip + 2)))
        y0 = max(0, int(math.floor(cy - self.r_tip - 2)))
        y1 = min(s.height_px, int(math.ceil(cy + self.r_tip + 2)))
        self.gbox = (0, y0, x1, y1)
        yy, xx = np.meshgrid(self.y[y0:y1], self.x[:x1], indexing="ij")
        rr, th = np.hypot(xx - cx, yy - cy), np.arctan2(yy - cy, xx - cx)
        self.g_r, self.g_th = rr, th
        # face brightness by radius: dark bore, bright boss, turned face, bright rim
        rel = rr / self.r_tip
        prof = np.interp(rel, [0.0, 0.14, 0.17, 0.36, 0.40, 0.62, 0.66, 0.80, 0.84, 0.95, 1.0],
                         [25, 30, 150, 170, 95, 110, 200, 190, 120, 210, 150])
        rings = 12.0 * np.cos(2 * np.pi * rr / 2.3) * ((rel > 0.4) & (rel < 0.62))
        self.g_base = prof + rings
        # angular harmonics fixed to the gear, cos(2πr/λ + β)·cos(nθ + ψ), with the pixel
        # area's average in closed form: over the pixel's radial extent (1 px) and over
        # its angular extent (1/r rad), sinc(1/λ)·sinc(n/(2πr))
        n = 40
        self.g_n = rng.integers(1, 120, n).astype(np.float64)
        lam = rng.uniform(4.0, 30.0, n)
        beta = rng.uniform(0, 2 * np.pi, n)
        amp = s.gear_texture * 16.0 * rng.normal(0, 1, n) / math.sqrt(n) * 2.0
        psi = rng.uniform(0, 2 * np.pi, n)
        inside = rr < self.r_tip + 2
        r_in, t_in = rr[inside][:, None], th[inside][:, None]
        att = _sinc(1.0 / lam)[None, :] * _sinc(self.g_n[None, :]
                                                / (2 * np.pi * np.maximum(r_in, 1.0)))
        radial = amp[None, :] * att * np.cos(2 * np.pi * r_in / lam + beta)
        ang = self.g_n[None, :] * t_in + psi
        bc = (radial * np.cos(ang)).astype(np.float32)
        bs = (radial * np.sin(ang)).astype(np.float32)
        self.g_inside = inside
        self.g_bc, self.g_bs = bc, bs
        # knurl annulus: outline sub-samples
        band = (rr > self.r_root - 2) & (rr < self.r_tip + 2)
        self.g_band = band
        ys, xs = np.nonzero(band)
        offs = (np.arange(_GEAR_SUB) + 0.5) / _GEAR_SUB - 0.5
        oy, ox = np.meshgrid(offs, offs, indexing="ij")
        px = xs[:, None] + ox.ravel()[None, :]
        py = ys[:, None] + y0 + oy.ravel()[None, :]
        self.band_r = np.hypot(px - cx, py - cy)
        self.band_th = np.arctan2(py - cy, px - cx)
        self.band_idx = (ys, xs)

    # --- per frame --------------------------------------------------------------------
    def _tooth_radius(self, phi: F64) -> F64:
        """Knurl outline: trapezoidal teeth, 24 per turn."""
        f = np.mod(phi * self.spec.gear_teeth / (2 * np.pi), 1.0)
        top = np.clip((np.abs(f - 0.45) * -1 + 0.30) / 0.12, 0.0, 1.0)
        return self.r_root + (self.r_tip - self.r_root) * top

    def _filament(self, shift_mm: float, speed_mm_s: float, gain: F64) -> tuple[F64, F64]:
        """Filament layer (BGR, rows × cols) and its coverage, columns fx0..fx1."""
        s = self.spec
        k = s.mm_per_px
        m = self.y * k - shift_mm                                  # material coordinate
        diam = s.filament_diameter_mm + s.width_wave_mm * np.sin(
            2 * np.pi * m / s.width_wavelength_mm + self.width_phase)
        r_rows = 0.5 * diam / k                                    # px, per row
        xc = s.filament_x_px
        left = xc - r_rows
        if s.teeth_marks:
            pitch = 2 * np.pi * s.gear_tip_mm / s.gear_teeth
            frac = np.mod(m / pitch + self.mark_phase, 1.0)
            notch = np.clip(1.0 - np.abs(frac - 0.5) / 0.18, 0.0, 1.0) * (
                self.y > s.contact_y_px + 6)
            left = left + notch * s.mark_depth_mm / k
        xs = self.fxs[None, :].astype(np.float32)
        r32 = r_rows.astype(np.float32)[:, None]
        cov = ((xs > left.astype(np.float32)[:, None]) & (xs < xc + r32)).astype(np.float32)
        u = np.clip((xs - np.float32(xc)) / r32, -1.0, 1.0)
        lam = 0.3 + 0.7 * np.sqrt(1.0 - u * u)
        spec_hl = np.float32(s.highlight) * np.exp(-(((u - s.highlight_u) / 0.06) ** 2))
        # texture: exact average over the pixel height and the exposure's travel
        b = 2 * np.pi * self.tf_m[None, :] * m[:, None] + self.t_phase[None, :]
        damp = self.t_amp * _sinc(self.tf_m * k) * _sinc(self.tf_m * speed_mm_s * s.exposure_s)
        tex = ((np.cos(b) * damp).astype(np.float32) @ self.t_cos_a
               - (np.sin(b) * damp).astype(np.float32) @ self.t_sin_a)
        grey = lam * (1.0 + tex) * cov
        hl = spec_hl * cov
        # average the sub-columns into pixels, then colour
        nr, nc = grey.shape[0], self.fx1 - self.fx0
        grey_px = grey.reshape(nr, nc, _SUB_X).mean(axis=2)
        hl_px = hl.reshape(nr, nc, _SUB_X).mean(axis=2)
        cov_px = cov.reshape(nr, nc, _SUB_X).mean(axis=2)
        val = grey_px[:, :, None] * self.fil_albedo[None, None, :].astype(np.float32) \
            + hl_px[:, :, None]
        return val * gain[:, None, None].astype(np.float32), cov_px

    def _motion(self, t: float) -> tuple[float, float, float, float]:
        if self._table is None or t > self._table[0][-1]:
            grid = np.arange(0.0, max(t, self.drive.t_s[-1]) + 0.1, 1e-3)
            self._table = (grid, *self.drive.distances(grid))
        grid, gd, fd = self._table
        gv, fv = self.drive.speeds(np.array([t]))
        return (float(np.interp(t, grid, gd)), float(np.interp(t, grid, fd)), float(gv[0]),
                float(fv[0]))

    def render(self, t: float, index: int = 0) -> RigFrame:
        """The frame exposed around time ``t`` (s)."""
        s = self.spec
        gear_d, fil_d, gear_v, fil_v = self._motion(t)
        h, w = s.height_px, s.width_px
        drift = 1.0 + s.drift * (0.7 * math.sin(2 * np.pi * t / 2.3)
                                 + 0.3 * math.sin(2 * np.pi * t / 0.71))
        tilt = 1.0 + 0.5 * s.drift * math.sin(2 * np.pi * t / 3.1) * (self.x / w - 0.5)
        img = self.bg.copy()
        fil, cov = self._filament(fil_d, fil_v, np.ones(h))
        sl = slice(self.fx0, self.fx1)
        img[:, sl] = img[:, sl] * (1.0 - cov[:, :, None]) + fil
        # gear: angle since t = 0 (positive feeds the filament down: clockwise on screen)
        alpha = gear_d / s.drive_radius_mm
        sweep = gear_v / s.drive_radius_mm * s.exposure_s
        x0, y0, x1, y1 = self.gbox
        blur = _sinc(self.g_n * sweep / (2 * np.pi))
        ca, sa = np.cos(self.g_n * alpha) * blur, np.sin(self.g_n * alpha) * blur
        # cos(n(θ − α) + ψ) = cos(nθ + ψ)cos(nα) + sin(nθ + ψ)sin(nα)
        tex = self.g_bc @ ca.astype(np.float32) + self.g_bs @ sa.astype(np.float32)
        face = self.g_base.copy()
        face[self.g_inside] += tex
        gcov = (self.g_r < self.r_root).astype(np.float64)
        times = ((np.arange(_GEAR_TIMES) + 0.5) / _GEAR_TIMES - 0.5) * sweep
        occ = np.zeros(self.band_r.shape[0])
        for dt_a in times:
            phi = self.band_th - (alpha + dt_a)
            occ += np.mean(np.clip(self._tooth_radius(phi) - self.band_r + 0.5, 0.0, 1.0),
                           axis=1)
        gcov[self.band_idx] = occ / _GEAR_TIMES
        # teeth flanks are darker than the rim
        face = np.where(self.g_r > self.r_root, 0.55 * face, face)
        metal = np.array([0.95, 1.0, 1.04])
        region = img[y0:y1, x0:x1]
        gc = gcov.astype(np.float32)[:, :, None]
        img[y0:y1, x0:x1] = region * (1.0 - gc) + (
            face.astype(np.float32)[:, :, None] * metal.astype(np.float32)[None, None, :]) * gc
        img *= (drift * tilt[None, :, None]).astype(np.float32)
        img = cv2.GaussianBlur(img, (0, 0), s.blur_px)
        if s.read_noise_dn > 0 or s.shot_noise:
            noise = self.rng.standard_normal(img.shape, dtype=np.float32)
            shot = np.maximum(img, 0.0) / 6.0 if s.shot_noise else 0.0
            img = img + noise * np.sqrt(s.read_noise_dn ** 2 + shot)
        bgr = np.clip(np.rint(img), 0, 255).astype(np.uint8)
        return RigFrame(index, t, bgr, gear_d, fil_d, gear_v, fil_v)

    def true_width_mm(self, t: float, rows: slice) -> float:
        """Mean true diameter over image rows ``rows`` at time ``t``, mm."""
        s = self.spec
        m = self.y[rows] * s.mm_per_px - self._motion(t)[1]
        diam = s.filament_diameter_mm + s.width_wave_mm * np.sin(
            2 * np.pi * m / s.width_wavelength_mm + self.width_phase)
        return float(np.mean(diam))


def render_clip(spec: RigSpec, drive: DriveProfile, n_frames: int) -> list[RigFrame]:
    """``n_frames`` frames at ``spec.fps``, exposures centred on ``i / fps``."""
    cam = RigCamera(spec, drive)
    return [cam.render(i / spec.fps, i) for i in range(n_frames)]


def write_mpeg4(frames: Sequence[RigFrame], path: Path, fps: float) -> Path:
    """Encode BGR frames as MPEG-4 part 2 (``FMP4``) with ``cv2.VideoWriter``."""
    return _write(frames, path, fps, "FMP4", "MPEG-4 part 2")


def write_ffv1(frames: Sequence[RigFrame], path: Path, fps: float) -> Path:
    """Encode BGR frames losslessly (FFV1) with ``cv2.VideoWriter``: the same frames as
    :func:`write_mpeg4` without the compression, to tell its share of an error."""
    return _write(frames, path, fps, "FFV1", "FFV1")


def _write(frames: Sequence[RigFrame], path: Path, fps: float, fourcc: str,
           codec: str) -> Path:
    h, w = frames[0].bgr.shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (w, h))
    if not writer.isOpened():
        raise RuntimeError(f"cv2.VideoWriter cannot write {codec} here")
    for f in frames:
        writer.write(f.bgr)
    writer.release()
    return path
