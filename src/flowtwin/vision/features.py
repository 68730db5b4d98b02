"""Image-level helpers of feature tracking: texture, noise, staleness, robust averages.

Small pure functions on arrays used by :class:`flowtwin.vision.track.RoiTracker`:
the Shi–Tomasi score in grey levels, a noise estimate, feature detection that only keeps
corners standing out of the noise [003 §2.2], detection of image regions that repeat the
previous frame, and the robust mean of the track displacements.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.vision.config import TrackingParams

__all__ = ["FeatureMemo", "detect_features", "is_stale", "min_eigenvalue_at",
           "min_eigenvalue_map", "noise_sigma_dn", "robust_mean", "window_std_at"]

U8 = npt.NDArray[np.uint8]
F32 = npt.NDArray[np.float32]

#: Immerkaer's noise kernel (difference of two Laplacians).
_IMMERKAER = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float32)
#: Block size of the Shi–Tomasi structure tensor, px.
_BLOCK = 7


def is_stale(crop: U8, previous: U8) -> bool:
    """Whether an image region repeats the previous frame's, wholly or in part.

    With sensor noise no row of real image data repeats bit for bit; a damaged frame that
    the decoder concealed with the previous frame's pixels (MJPEG, H.264), or a driver
    that repeats a buffer, does. A region is stale when at least ``max(4, 5 %)`` of its
    rows are bit-identical to the previous frame's and not uniform (uniform rows, e.g.
    clipped black, carry no information either way).

    Parameters
    ----------
    crop, previous
        The region in this and the previous frame, shape ``(H, W)``, uint8.

    Returns
    -------
    bool
    """
    need = max(4, int(0.05 * crop.shape[0]))
    same = np.all(crop == previous, axis=1)
    if int(same.sum()) < need:
        return False
    same &= crop.max(axis=1) > crop.min(axis=1)
    return int(same.sum()) >= need


def robust_mean(values: npt.NDArray[np.float64], scale: npt.NDArray[np.float64] | None = None,
                *, floor: float = 0.1, k: float = 3.0
                ) -> tuple[float, npt.NDArray[np.bool_]]:
    """Mean of the values within ``k`` robust standard deviations of their median.

    Parameters
    ----------
    values
        Samples, shape ``(N,)``.
    scale
        Per-sample factor converting a deviation into px (the lever arm for angles),
        shape ``(N,)``; default 1.
    floor
        Smallest acceptance half-width, px (tracks agreeing to better than this are
        never rejected).
    k
        Acceptance in robust standard deviations (``1.4826·MAD``).

    Returns
    -------
    mean : float
        Weighted (by ``scale²``) mean of the inliers; NaN if there are none.
    inliers : numpy.ndarray of bool
        Which samples were used, shape ``(N,)``.
    """
    if values.size == 0:
        return math.nan, np.zeros(0, dtype=bool)
    lever = np.ones_like(values) if scale is None else scale
    med = float(np.median(values))
    dev = (values - med) * lever
    mad = float(np.median(np.abs(dev)))
    inl = np.abs(dev) <= max(k * 1.4826 * mad, floor)
    w = lever[inl] ** 2
    return float(np.sum(values[inl] * w) / np.sum(w)), inl


def min_eigenvalue_map(gray: U8, *, block: int = _BLOCK) -> F32:
    """Shi–Tomasi score: smaller eigenvalue of the local structure tensor, (DN/px)².

    Gradients are 3×3 Sobel derivatives divided by 8 (grey levels per pixel), their
    products averaged over a ``block × block`` window.

    Parameters
    ----------
    gray
        Image, shape ``(H, W)``, uint8.
    block
        Averaging window side, px.

    Returns
    -------
    numpy.ndarray
        Score map, shape ``(H, W)``, float32.
    """
    img = gray.astype(np.float32)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    a = cv2.boxFilter(gx * gx, -1, (block, block))
    b = cv2.boxFilter(gx * gy, -1, (block, block))
    c = cv2.boxFilter(gy * gy, -1, (block, block))
    half = 0.5 * (a - c)
    return np.asarray(0.5 * (a + c) - np.sqrt(half * half + b * b), dtype=np.float32)


def min_eigenvalue_at(gray: U8, xy: npt.NDArray[np.float64], *, block: int = _BLOCK) -> F32:
    """:func:`min_eigenvalue_map` at the pixels nearest to points ``xy`` only (the same
    gradients and reflected border; the windows summed at those points instead of
    box-filtering the whole map).

    Parameters
    ----------
    gray
        Image, shape ``(H, W)``, uint8.
    xy
        Points ``(x, y)``, shape ``(N, 2)``, px.
    block
        Averaging window side, px (odd).

    Returns
    -------
    numpy.ndarray
        Scores, shape ``(N,)``, (DN/px)².
    """
    img = gray.astype(np.float32)
    half = block // 2
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    gx = cv2.copyMakeBorder(gx, half, half, half, half, cv2.BORDER_REFLECT_101)
    gy = cv2.copyMakeBorder(gy, half, half, half, half, cv2.BORDER_REFLECT_101)
    ix = np.clip(np.rint(xy[:, 0]).astype(np.intp), 0, gray.shape[1] - 1)
    iy = np.clip(np.rint(xy[:, 1]).astype(np.intp), 0, gray.shape[0] - 1)
    offs = np.arange(block)
    rows = (iy[:, None] + offs[None, :])[:, :, None]
    cols = (ix[:, None] + offs[None, :])[:, None, :]
    wx, wy = gx[rows, cols], gy[rows, cols]                       # (N, block, block)
    n = float(block * block)
    a = (wx * wx).sum(axis=(1, 2)) / n
    b = (wx * wy).sum(axis=(1, 2)) / n
    c = (wy * wy).sum(axis=(1, 2)) / n
    h2 = 0.5 * (a - c)
    return np.asarray(0.5 * (a + c) - np.sqrt(h2 * h2 + b * b), dtype=np.float32)


def window_std_at(img: U8, xy: npt.NDArray[np.float64], win: int) -> npt.NDArray[np.float64]:
    """Standard deviation of the grey levels in the ``win × win`` window around the pixel
    nearest to each point (reflected border, as ``cv2.boxFilter``), DN.

    Parameters
    ----------
    img
        Image, shape ``(H, W)``, uint8.
    xy
        Points ``(x, y)``, shape ``(N, 2)``, px.
    win
        Window side, px (odd).

    Returns
    -------
    numpy.ndarray
        Standard deviations, shape ``(N,)``.
    """
    if len(xy) == 0:
        return np.zeros(0)
    half = win // 2
    f = cv2.copyMakeBorder(img, half, half, half, half, cv2.BORDER_REFLECT_101)
    ix = np.clip(np.rint(xy[:, 0]).astype(np.intp), 0, img.shape[1] - 1)
    iy = np.clip(np.rint(xy[:, 1]).astype(np.intp), 0, img.shape[0] - 1)
    offs = np.arange(win)
    v = f[(iy[:, None] + offs[None, :])[:, :, None],
          (ix[:, None] + offs[None, :])[:, None, :]].reshape(len(ix), -1).astype(np.float64)
    return np.asarray(np.std(v, axis=1), dtype=np.float64)


def noise_sigma_dn(gray: U8) -> float:
    """Standard deviation of the pixel noise of an image, DN (Immerkaer's estimator).

    The image is filtered with the difference of two Laplacians
    ``[[1, −2, 1], [−2, 4, −2], [1, −2, 1]]``, which cancels smooth image structure;
    ``σ = sqrt(π/2)·Σ|I * N| / (6·(W − 2)·(H − 2))`` (J. Immerkaer, "Fast noise variance
    estimation", CVIU 64 (1996) 300–302).

    Parameters
    ----------
    gray
        Image, shape ``(H, W)`` with ``H, W >= 3``, uint8.

    Returns
    -------
    float
        Noise standard deviation, DN.
    """
    h, w = gray.shape[:2]
    if h < 3 or w < 3:
        return 0.0
    r = cv2.filter2D(gray.astype(np.float32), -1, _IMMERKAER)[1:-1, 1:-1]
    return float(math.sqrt(math.pi / 2.0) * np.abs(r).sum() / (6.0 * (w - 2) * (h - 2)))


def detect_features(gray: U8, params: TrackingParams, *, mask: U8 | None = None,
                    min_distance_px: int | None = None,
                    noise_region: tuple[slice, slice] | None = None
                    ) -> npt.NDArray[np.float64]:
    """Shi–Tomasi features that stand out of the noise enough to track [003 §2.2].

    ``goodFeaturesToTrack`` picks up to ``max_tracks`` corners. A corner is kept only if
    its smaller structure-tensor eigenvalue ``λ`` (:func:`min_eigenvalue_map`) reaches
    both ``min_texture_eig`` and ``min_texture_snr`` times the value pure noise gives,
    ``0.1875·σ²`` (the variance of a 3×3 Sobel/8 derivative of white noise of
    ``σ`` = :func:`noise_sigma_dn`). Edges (one large eigenvalue: the aperture problem)
    and noise therefore give no features, and a texture-less region is flagged, not
    tracked.

    Parameters
    ----------
    gray
        Raw (not normalised) grey image, shape ``(H, W)``, uint8.
    params
        Tracking parameters (``max_tracks``, ``min_texture_eig``, ``min_texture_snr``).
    mask
        Where features may be, shape ``(H, W)``, uint8 (non-zero = allowed).
    min_distance_px
        Smallest distance between features (default ``win_px // 4``), px.
    noise_region
        ``(rows, columns)`` slices where the noise is estimated (default: the bounding
        box of ``mask``, or the whole image).

    Returns
    -------
    numpy.ndarray
        Feature positions ``(x, y)``, shape ``(N, 2)``, px.
    """
    dist = max(3, params.win_px // 4) if min_distance_px is None else min_distance_px
    pts = cv2.goodFeaturesToTrack(gray, maxCorners=params.max_tracks, qualityLevel=0.01,
                                  minDistance=dist, mask=mask, blockSize=_BLOCK)
    if pts is None:
        return np.zeros((0, 2), np.float64)
    xy = pts[:, 0, :].astype(np.float64)
    if noise_region is None and mask is not None:
        bx, by, bw, bh = cv2.boundingRect(mask)
        noise_region = (slice(by, by + bh), slice(bx, bx + bw))
    sigma = noise_sigma_dn(gray if noise_region is None else gray[noise_region])
    floor = max(params.min_texture_eig, params.min_texture_snr * 0.1875 * sigma * sigma)
    return xy[min_eigenvalue_at(gray, xy) >= floor]


class FeatureMemo:
    """:func:`detect_features` of the same frames with the same mask, remembered: the
    axis estimate makes keyframes of the same frames in several passes.

    Parameters
    ----------
    params
        Tracking parameters.
    mask
        Where features may be (non-zero), shape ``(H, W)``, uint8.
    """

    def __init__(self, params: TrackingParams, mask: U8) -> None:
        self.params = params
        self.mask = mask
        bx, by, bw, bh = cv2.boundingRect(mask)
        self.box = (slice(by, by + bh), slice(bx, bx + bw))
        self._found: dict[int, npt.NDArray[np.float64]] = {}

    def __call__(self, index: int, crop: U8) -> npt.NDArray[np.float64]:
        """Features of frame ``index`` (its crop ``crop``), detected once."""
        if index not in self._found:
            self._found[index] = detect_features(crop, self.params, mask=self.mask,
                                                 noise_region=self.box)
        return self._found[index].copy()
