"""The silhouette edge model of a shaded cylinder (flowtwin.vision.edge_model): its closed
form, its fit, and the width of cylinders rendered here by brute force (supersampled
shading, numerical blur, pixel averaging) whose silhouette is known exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import gamma, ndtr

from flowtwin.vision.edge_model import (
    EdgeProfile,
    blurred_pow15_edge,
    blurred_sqrt_edge,
    fit_edge_pair,
)
from flowtwin.vision.silhouette import clip_model
from flowtwin.vision.width import measure_width_px, refit_width, refit_widths


def test_blurred_square_root_against_quadrature_and_closed_forms() -> None:
    # S(0) = ∫₀^∞ √t φ(t) dt = 2^(−1/4) Γ(3/4) / √(2π)
    assert blurred_sqrt_edge(np.array([0.0]))[0] == pytest.approx(
        2 ** -0.25 * gamma(0.75) / math.sqrt(2 * math.pi), rel=1e-6)
    # against a brute-force quadrature (t = u² removes the singularity)
    for z in (-4.0, -1.3, 0.4, 2.0, 7.5, 11.9, 12.1, 30.0):
        top = math.sqrt(max(z, 0.0) + 9.0)
        uu = np.linspace(0.0, top, 200001)
        f = 2 * uu * uu * np.exp(-0.5 * (z - uu * uu) ** 2) / math.sqrt(2 * math.pi)
        ref = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(uu)))
        assert blurred_sqrt_edge(np.array([z]))[0] == pytest.approx(ref, rel=2e-5, abs=1e-9)
    # the next term, ∫₀^∞ t^1.5 φ(z − t) dt: S₃(0) = 2^(1/4) Γ(5/4) / √(2π)
    assert blurred_pow15_edge(np.array([0.0]))[0] == pytest.approx(
        2 ** 0.25 * gamma(1.25) / math.sqrt(2 * math.pi), rel=1e-6)
    for z in (-1.0, 3.0, 11.9, 12.1):
        top = math.sqrt(max(z, 0.0) + 9.0)
        uu = np.linspace(0.0, top, 200001)
        f = 2 * uu ** 4 * np.exp(-0.5 * (z - uu * uu) ** 2) / math.sqrt(2 * math.pi)
        ref = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(uu)))
        assert blurred_pow15_edge(np.array([z]))[0] == pytest.approx(ref, rel=2e-5)
    # far inside it is √z; far outside nothing
    assert blurred_sqrt_edge(np.array([400.0]))[0] == pytest.approx(20.0, rel=1e-6)
    assert blurred_sqrt_edge(np.array([-20.0]))[0] == pytest.approx(0.0, abs=1e-15)


def _model_profile(x: np.ndarray, inside: int, edge: float, sigma: float, a: float,
                   b: float, c: float, bg: float, slope: float) -> np.ndarray:
    s = inside * (x - edge)
    z = s / sigma
    ramp = sigma * (z * ndtr(z) + np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi))
    return (bg + slope * s + a * ndtr(z) + c * ramp
            + b * math.sqrt(sigma) * blurred_sqrt_edge(z))


@pytest.mark.parametrize(("a", "b"), [(60.0, 0.0), (20.0, 35.0), (0.0, 40.0)])
def test_fit_recovers_the_edge_of_a_model_profile(a: float, b: float) -> None:
    """Exact model profiles: recovered to 0.12 px when one frame fits everything (a
    pure square-root limb at 2 px blur leaves a long flat valley of the residual
    along blur and position, searched on a grid); with 0.2 DN of noise, 0.06 px when
    the blur and the limb shape are known, 0.3 px when one frame must fit them too
    (they trade off against the position: why a clip fits them jointly)."""
    rng = np.random.default_rng(7)
    x = np.arange(-6.0, 11.0) + 0.23
    mix = (math.atan2(b, a), math.atan2(b, 0.8 * a))
    for sigma in (0.7, 1.2, 2.0):
        left = _model_profile(x, 1, 0.37, sigma, a, b, 2.0, 40.0, 0.3)
        right = _model_profile(-x, -1, -0.61, sigma, a * 0.8, b, -1.0, 30.0, -0.2)
        exact = (EdgeProfile(x, left, 1, 100), EdgeProfile(-x[::-1], right[::-1], -1, 100))
        fl, fr = fit_edge_pair(*exact)
        assert fl.offset_px == pytest.approx(0.37, abs=0.12), sigma
        assert fr.offset_px == pytest.approx(-0.61, abs=0.12), sigma
        assert fl.blur_px == pytest.approx(sigma, rel=0.06)
        noisy = (EdgeProfile(x, left + rng.normal(0, 0.2, x.size), 1, 100),
                 EdgeProfile(-x[::-1], (right + rng.normal(0, 0.2, x.size))[::-1], -1, 100))
        fl, fr = fit_edge_pair(*noisy, blur_px=sigma, mix=mix)
        assert fl.offset_px == pytest.approx(0.37, abs=0.06), sigma
        assert fr.offset_px == pytest.approx(-0.61, abs=0.06), sigma
        fl, fr = fit_edge_pair(*noisy)
        assert fl.ok and fr.ok
        assert fl.offset_px == pytest.approx(0.37, abs=0.3), sigma
        assert fr.offset_px == pytest.approx(-0.61, abs=0.3), sigma


def _cylinder(shade, *, radius: float = 70.4, xc: float = 101.3, blur: float = 1.2,
              h: int = 60, w: int = 200, bg: float = 35.0, albedo: float = 200.0,
              tilt: float = 0.01, noise: float = 1.0, seed: int = 0) -> np.ndarray:
    """A front-lit cylinder rendered by brute force: radiance ``albedo·shade(cos θ)`` on
    32 sub-columns per pixel, a Gaussian blur by direct convolution, pixel averages."""
    sub = 32
    xs = (np.arange(w * sub) + 0.5) / sub - 0.5
    k = np.arange(-int(6 * blur * sub), int(6 * blur * sub) + 1) / sub
    kernel = np.exp(-0.5 * (k / blur) ** 2)
    kernel /= kernel.sum()
    rng = np.random.default_rng(seed)
    img = np.empty((h, w))
    for y in range(h):
        u = (xs - (xc + tilt * (y - (h - 1) / 2))) / (radius / math.cos(math.atan(tilt)))
        inside = np.abs(u) < 1
        row = np.full(xs.size, bg)
        row[inside] = albedo * shade(np.sqrt(1 - u[inside] ** 2))
        row = np.convolve(row, kernel, mode="same")
        img[y] = row.reshape(w, sub).mean(axis=1)
    img += rng.normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


SHADES = {
    "lambertian+ambient (renderer 2)": lambda c: 0.3 + 0.7 * c,
    "dark limb (the real clip)": lambda c: 0.12 + 0.88 * c,
    "bright limb (renderer 1)": lambda c: 0.7 + 0.3 * c,
    "diffuse + cos² lobe": lambda c: 0.2 + 0.5 * c + 0.3 * c * c,
}


@pytest.mark.parametrize("name", list(SHADES))
def test_width_of_a_shaded_cylinder_is_its_silhouette(name: str) -> None:
    """The silhouette is at ±R from the axis whatever the shading; the derivative
    extrema of the blurred image lie inside it, the fitted silhouettes do not."""
    shade = SHADES[name]
    for blur, tol in ((0.6, 0.15), (1.2, 0.3), (2.0, 0.3)):
        ms = [measure_width_px(_cylinder(shade, blur=blur, seed=s)) for s in range(4)]
        sils = [m.silhouette for m in ms if m.silhouette is not None]
        assert len(sils) == 4, name
        # as a clip does it: one blur and one limb shape for the frames, jointly
        sigma, mix = clip_model([sl.profiles for sl in sils],
                                [(sl.left, sl.right) for sl in sils],
                                float(np.median([m.blur_px for m in ms])))
        assert sigma == pytest.approx(math.hypot(blur, 1 / math.sqrt(12)), rel=0.12)
        for m in ms:
            m = refit_width(m, sigma, 60, mix=mix)
            assert m.width_px == pytest.approx(140.8, abs=tol), (name, blur)
        # the clip's refit in one vectorised pass gives each frame's own refit
        together = refit_widths(ms, sigma, 60, mix=mix)
        for m, t in zip(ms, together, strict=True):
            one = refit_width(m, sigma, 60, mix=mix)
            assert t.width_px == pytest.approx(one.width_px, abs=1e-9)
            assert t.silhouette is not None and one.silhouette is not None
            assert t.silhouette.left.step_dn == pytest.approx(one.silhouette.left.step_dn,
                                                              rel=1e-9)
    # the derivative method's inward bias, for contrast (grows with the shading rise)
    m = measure_width_px(_cylinder(SHADES["dark limb (the real clip)"], blur=1.2))
    assert m.gradient_width_px < 140.8 - 1.0


def test_a_darker_limb_than_the_background_does_not_run_away() -> None:
    """Without the sign constraint a step below the background plus a steep rise fits
    a bright filament's edge 3 px outside it (seen on the real clip); with it the fit
    stays on the silhouette."""
    img = _cylinder(lambda c: 0.1 + 0.9 * c, bg=22.0, albedo=130.0, blur=1.4, noise=1.5)
    m = measure_width_px(img)
    assert m.ok and m.width_px == pytest.approx(140.8, abs=0.3)
    assert m.silhouette is not None and m.silhouette.polarity == 1.0
    assert m.silhouette.left.step_dn >= -22.0 and m.silhouette.left.rise_dn >= 0
