"""What the synthetic slip camera looks at: geometry, optics and defects of one scene.

The layout follows [003 Fig. 2]: a vertical filament fed downwards, a toothed drive gear
on its left (axis in the image), a smooth spring-loaded pinch bearing on its right. At the
default ~20 µm/px of [003 §2.1] a 640×480 frame sees 12.8 × 9.6 mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flowtwin.errors import VisionError
from flowtwin.vision.config import TrackingParams, VisionConfig
from flowtwin.vision.roi import Roi, RoiSet

__all__ = ["SceneSpec"]


@dataclass(frozen=True, slots=True)
class SceneSpec:
    """Geometry, appearance and defects of a synthetic camera scene.

    Attributes
    ----------
    width_px, height_px
        Frame size, px.
    mm_per_px
        Image scale, mm/px (the true ``k_cal``).
    fps
        Nominal frame rate, 1/s.
    exposure_s
        Exposure time (motion blur), s.
    filament_x_px
        Column of the filament axis, px.
    nominal_width_mm
        Filament width that places the gear and bearing, mm.
    gear_center_y_px
        Row of the gear axis (the contact row), px.
    gear_tip_radius_mm, gear_teeth, tooth_depth_mm
        Toothed drive gear ([003]: 24 teeth, 8 mm outer diameter).
    bite_mm
        Depth of the teeth in the filament; the drive radius is ``tip − bite``, mm.
    bearing_radius_mm
        Pinch bearing radius (smooth, it looks static), mm.
    filament_dn, background_dn
        Grey levels of filament and background before gain and noise.
    shading
        Fraction of the filament brightness that follows a Lambertian cylinder
        ``sqrt(1 − u²)`` across its width (0 = flat, like a backlit silhouette).
    filament_texture
        Filament texture contrast (1 = 12 % rms of the filament brightness).
    texture_gaps_mm
        Ranges ``(m0, m1)`` of the material coordinate (mm; material at row ``y`` at
        ``t = 0`` has ``m = y·mm_per_px``) where the texture contrast is ``gap_texture``.
    gap_texture
        Texture contrast inside the gaps (0 = none).
    glossy
        Strength of a static specular highlight on the filament (0 = matte).
    gear_face_texture
        Contrast of the random texture on the gear face and shaft end (0 = plain).
    gear_rings
        Contrast of the concentric turning marks on the gear face.
    width_variation_mm, width_wavelength_mm
        Sinusoidal width variation along the filament (added to the motion's width), mm.
    noise_dn
        Read noise, DN rms; ``shot_noise`` adds photon noise ``sqrt(I/8)``.
    blur_px
        Optical (defocus) blur, Gaussian sigma in px.
    gain_amplitude, gain_period_s
        Exposure/illumination change: gain ``1 + a·sin(2πt/T)``.
    dropped_frames, blank_frames, duplicate_frames
        Capture indices that are dropped (not delivered), blank (lens cap / glitch) or a
        repeat of the previous image with a new timestamp.
    timestamp_jitter_s
        Random jitter of the capture times (recorded in the timestamps), s rms.
    seed
        Seed of every random texture and of the noise.
    """

    width_px: int = 640
    height_px: int = 480
    mm_per_px: float = 0.02
    fps: float = 30.0
    exposure_s: float = 0.004
    filament_x_px: float = 430.0
    nominal_width_mm: float = 1.75
    gear_center_y_px: float = 240.0
    gear_tip_radius_mm: float = 4.0
    gear_teeth: int = 24
    tooth_depth_mm: float = 0.25
    bite_mm: float = 0.08
    bearing_radius_mm: float = 5.0
    filament_dn: float = 170.0
    background_dn: float = 45.0
    shading: float = 0.3
    filament_texture: float = 1.0
    texture_gaps_mm: tuple[tuple[float, float], ...] = ()
    gap_texture: float = 0.0
    glossy: float = 0.0
    gear_face_texture: float = 1.0
    gear_rings: float = 0.5
    width_variation_mm: float = 0.02
    width_wavelength_mm: float = 7.0
    noise_dn: float = 2.0
    shot_noise: bool = True
    blur_px: float = 0.7
    gain_amplitude: float = 0.0
    gain_period_s: float = 1.0
    dropped_frames: tuple[int, ...] = ()
    blank_frames: tuple[int, ...] = ()
    duplicate_frames: tuple[int, ...] = ()
    timestamp_jitter_s: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        checks = {
            "width_px": (64, 8192), "height_px": (64, 8192), "mm_per_px": (1e-4, 1.0),
            "fps": (0.1, 10000.0), "exposure_s": (0.0, 1.0), "nominal_width_mm": (0.1, 10.0),
            "gear_tip_radius_mm": (0.5, 50.0), "gear_teeth": (3, 400),
            "tooth_depth_mm": (0.0, 5.0), "bite_mm": (0.0, 1.0),
            "bearing_radius_mm": (0.5, 50.0), "filament_texture": (0.0, 5.0), "shading": (0.0, 1.0),
            "gap_texture": (0.0, 5.0), "glossy": (0.0, 2.0), "gear_face_texture": (0.0, 5.0),
            "gear_rings": (0.0, 5.0), "width_variation_mm": (0.0, 1.0),
            "width_wavelength_mm": (0.1, 1000.0), "noise_dn": (0.0, 100.0),
            "blur_px": (0.0, 10.0), "gain_amplitude": (0.0, 0.9),
            "gain_period_s": (1e-3, 1e4), "timestamp_jitter_s": (0.0, 1.0),
        }
        for name, (lo, hi) in checks.items():
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and lo <= value <= hi):
                raise VisionError("synthetic scene parameter out of range",
                                  field=f"scene.{name}", value=value,
                                  allowed=f"{lo} <= {name} <= {hi}")
        if self.bite_mm >= self.gear_tip_radius_mm:
            raise VisionError("teeth bite deeper than the gear radius", field="scene.bite_mm",
                              value=self.bite_mm, allowed="< gear_tip_radius_mm")

    # --- derived geometry (px unless named otherwise) -------------------------------
    @property
    def drive_radius_mm(self) -> float:
        """Effective drive radius ``R = tip − bite``: gear speed is ``ω·R`` [003 Eq. 3]."""
        return self.gear_tip_radius_mm - self.bite_mm

    @property
    def filament_left_px(self) -> float:
        """Nominal left (gear-side) filament edge, px."""
        return self.filament_x_px - 0.5 * self.nominal_width_mm / self.mm_per_px

    @property
    def filament_right_px(self) -> float:
        """Nominal right (bearing-side) filament edge, px."""
        return self.filament_x_px + 0.5 * self.nominal_width_mm / self.mm_per_px

    @property
    def gear_center_px(self) -> tuple[float, float]:
        """Gear axis ``(x, y)``: the drive radius touches the nominal left edge."""
        return (self.filament_left_px - self.drive_radius_mm / self.mm_per_px,
                self.gear_center_y_px)

    @property
    def bearing_center_px(self) -> tuple[float, float]:
        """Pinch-bearing axis ``(x, y)``: touching the nominal right edge."""
        return (self.filament_right_px + self.bearing_radius_mm / self.mm_per_px,
                self.gear_center_y_px)

    def suggested_rois(self) -> RoiSet:
        """ROIs that fit this scene: gear face, filament above and below the contact."""
        mm = self.mm_per_px
        cx, cy = self.gear_center_px
        r_tip = self.gear_tip_radius_mm / mm
        r_root = (self.gear_tip_radius_mm - self.tooth_depth_mm) / mm
        # gear: rectangle inscribed in the root circle, clipped to the frame
        ax, ay = 0.55 * r_root, 0.80 * r_root
        gx0, gy0 = max(0, math.ceil(cx - ax)), max(0, math.ceil(cy - ay))
        gx1 = min(self.width_px, math.floor(cx + ax))
        gy1 = min(self.height_px, math.floor(cy + ay))
        # before: rows where neither the gear nor the bearing come near the filament
        xl, xr = self.filament_left_px, self.filament_right_px
        margin = 12.0
        bx, _ = self.bearing_center_px
        r_b = self.bearing_radius_mm / mm
        clear_gear = math.sqrt(max(r_tip ** 2 - (xl - margin - 4 - cx) ** 2, 0.0))
        clear_bear = math.sqrt(max(r_b ** 2 - (bx - xr - margin - 4) ** 2, 0.0))
        b_y1 = int(cy - max(clear_gear, clear_bear) - 4)
        b_y0 = max(4, b_y1 - 150)
        before = Roi("before", int(math.floor(xl - margin)), b_y0,
                     int(math.ceil(xr + margin) - math.floor(xl - margin)), b_y1 - b_y0)
        # after: inside the filament, below the contact zone
        contact = math.sqrt(max(r_tip ** 2 - (xl - cx) ** 2, 0.0))
        a_y0 = int(cy + contact + 20)
        a_y1 = min(self.height_px - 4, a_y0 + 180)
        a_x0, a_x1 = int(math.ceil(xl + 6)), int(math.floor(xr - 6))
        after = Roi("after", a_x0, a_y0, a_x1 - a_x0, a_y1 - a_y0)
        gear = Roi("gear", gx0, gy0, gx1 - gx0, gy1 - gy0)
        return RoiSet(gear=gear, before=before, after=after)

    def vision_config(self, *, rotation: bool | None = True, known_scale: bool = True,
                      tracking: TrackingParams | None = None) -> VisionConfig:
        """A measurement configuration for this scene.

        Parameters
        ----------
        rotation
            ``True``: give the gear centre and drive radius (rotation mode); ``False``:
            tangential mode; ``None``: neither, the axis is estimated from the motion.
        known_scale
            Give ``mm_per_px`` (true) or calibrate from the nominal width [003 Eq. 4].
        tracking
            Tracking parameters (default: :class:`TrackingParams` defaults).
        """
        return VisionConfig(
            rois=self.suggested_rois(),
            mm_per_px=self.mm_per_px if known_scale else None,
            calib_width_mm=None if known_scale else self.nominal_width_mm,
            gear_center_px=self.gear_center_px if rotation else None,
            gear_radius_mm=self.drive_radius_mm if rotation else None,
            gear_method="tangential" if rotation is False else "auto",
            diameter_mm=self.nominal_width_mm,
            tracking=tracking or TrackingParams())
