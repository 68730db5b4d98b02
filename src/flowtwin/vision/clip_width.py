"""The width over a whole recording: one blur for the clip, and refusals a frame cannot make.

Per frame, :func:`~flowtwin.vision.width.measure_width_px` finds the filament's edges and
fits their silhouettes (:mod:`flowtwin.vision.silhouette`). Over the recording:

1. **One blur, one limb shape.** The optics' blur is the same in every frame (fixed
   focus; motion blur runs along the filament, not across it), and so is the shape of
   each edge's limb — the split between the step and the square-root rise,
   ``atan2(B, A)``, set by the material and the lighting (a drifting gain scales both)
   — but a single frame's fit of them trades off against the edge position (texture
   at the limb, noise). The blur is fitted freely in the first :data:`BLUR_FRAMES`
   frames whose edges were found, and their median fixed for the later frames; each
   frame's limb shapes are fitted with it (the running values). At the end
   (:meth:`ClipWidth.finish`) the blur and the shape of each edge are fitted jointly
   (:func:`~flowtwin.vision.silhouette.clip_model`: the least residual summed over
   the profiles) on the **means of groups** of :data:`SHAPE_GROUP` consecutive
   frames' crops (:class:`FrameGroups`; up to :data:`SHAPE_FRAMES` groups over the
   clip), and every frame is refitted with them: only the edges' positions, the
   background and the amplitudes are per frame. (The widths are final when the run
   ends.) Why group means: the blur and the limb's shape are nearly interchangeable
   within the blur (a ridge of equal residual along which the edge moves), and the
   filament's texture, which moves with the material, perturbs each frame's profile
   by a few tenths of a DN; summed over single frames, the least-squares fit slides
   along that ridge towards the shapes that absorb the texture best (on renderer 2,
   seed 2: limb shape 0.53 rad instead of the texture-free 0.73 rad at the true blur,
   and every width −0.3 px). In a mean over consecutive frames the texture has moved
   and averages out, while the silhouette, the blur and the shading stay (a gain
   change between the frames scales the whole profile, not its shape); groups end
   where the edges move by more than :data:`GROUP_SHIFT_PX`. A texture that does not
   move (a still filament, stripes along it) is not averaged out.
2. **Rough edges.** A silhouette is straight: its rows' edge points scatter about the
   edge line by the noise only (0.25–0.48 px on the real clip of [003], up to 0.85 px on
   renderer 2 at 2 px blur, both edges alike). Where the gear's teeth cover the
   filament's edge, or teeth marks notch it, that edge's rows scatter by 1–2.5 px,
   several times the other edge's (a lossy codec smooths this: 0.5 px against 0.14 px
   for a marked edge under MPEG-4, see :data:`ROUGH_PX`). One frame's scatter is noisy;
   the clip's median is not: when the rougher edge scatters by more than
   :data:`ROUGH_PX` *and* :data:`ROUGH_RATIO` times the other, or by more than
   :data:`ROUGH_MAX_PX` whatever the other does, every width of the clip is refused —
   what the ROI sees is not the filament's silhouette, and no frame of it can be
   trusted.
3. **The gear's contact zone.** With the gear axis known (given or estimated), the
   contact radius ``R_c`` is the distance from the axis to the filament's near edge; the
   teeth reach ``R_c + δ`` (the bite and a margin, :data:`TOOTH_REACH_MM`), so rows within
   ``√((R_c + δ)² − R_c²)`` of the axis's row see teeth over the edge. A ``before`` ROI
   that reaches them is refused.
4. **Stripes along the filament.** Texture that runs along the filament moves along
   itself: it never changes in the image, so neither the frame groups' means nor the
   rows' mean average it out. Foreshortened towards the limb it becomes a ripple finer
   than the blur, which the edge model takes for the limb's shading and moves the
   silhouette with (renderer 2: both edges 0.24–0.57 px off, the width up to 0.63 px
   in every frame of a clip, or right by the two errors' chance cancellation). Further
   in, where the stripes are resolved, the profile departs from a smoothly shaded
   cylinder (:func:`~flowtwin.vision.silhouette.interior_ripple`); when it does by more
   than :data:`RIPPLE_MAX` of the edge's contrast beside either edge (median over the
   groups' means), every width of the clip is refused: the image does not tell the
   silhouette from the stripes to half a pixel.
5. **Too few frame groups under an inter-frame codec.** The blur and the limb's shape
   are told apart by the profile's content at about 0.1–0.3 cycle/px, which is where
   the codec's 8×8 DCT quantization acts; it moves the fitted blur by up to ±0.1 px and
   the limb shapes with it (a width error of about −2 px per px of blur). An
   inter-frame codec (MPEG-4 part 2, H.264, …) predicts each frame from earlier ones,
   so the frames of a short clip share a few codings of the static edge and their
   means do not average the codec's error out: on renderer 2, a 24-frame MPEG-4 clip
   (3 groups) of a texture-free filament read +0.6 px in every frame (its groups agree
   on the wrong blur: 1.10–1.13 px with any one left out, against 1.23 px), its
   48-frame version +0.1 px. A clip from such a codec whose blur and limb shapes rest
   on fewer than :data:`MIN_GROUPS_INTER` groups is refused.
6. **A frame's width from its neighbours.** What is left after 1–5 differs from frame
   to frame by more than the filament does between frames a few apart: the codec's
   quantizer changes with a frame's place in its group of pictures (on renderer 2 the
   frames beyond 0.5 px sat beside the key frames). Every width kept is replaced by the
   local line through its clip's widths over up to
   :data:`~flowtwin.vision.width_series.WINDOW_FRAMES` frames, no more than the filament
   travels through the ROI's height (:mod:`flowtwin.vision.width_series`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from flowtwin.vision.readings import Quality
from flowtwin.vision.roi import Roi
from flowtwin.vision.silhouette import Silhouette, clip_model, interior_ripple
from flowtwin.vision.summarize import RowLog
from flowtwin.vision.width import EdgeMeasurement, measure_width_px, refit_widths
from flowtwin.vision.width_series import MIN_FRAMES, local_line, neighbour_frames

__all__ = ["BLUR_FRAMES", "MIN_GROUPS_INTER", "RIPPLE_MAX", "ROUGH_MAX_PX", "ROUGH_PX",
           "ROUGH_RATIO", "TOOTH_REACH_MM", "ClipWidth", "contact_rows", "is_clean"]

#: Frames whose blur is fitted freely before the clip's blur is fixed.
BLUR_FRAMES = 15
#: Frames (spread over the clip) whose residuals decide the clip's blur and limb shapes.
SHAPE_FRAMES = 64
#: Consecutive frames whose ``before`` crops are averaged into one image for the clip's
#: blur and limb shapes (the filament's texture moves with it, its silhouette does not).
SHAPE_GROUP = 8
#: A frame whose edge lines (at the ROI's middle row) lie further than this from the
#: group's first frame's starts a new group, px.
GROUP_SHIFT_PX = 0.5
#: Clip-median row scatter of the rougher edge above which, with :data:`ROUGH_RATIO`,
#: the edges are not a silhouette, px. A lossy codec smooths the rows' scatter: renderer
#: 2's seed 35 (rows 130-170), whose left edge scatters by 1.0 px against 0.3 px
#: losslessly (refused), scatters by 0.52 against 0.14 px under MPEG-4 and read 0.26 px
#: narrow there; the clean edges scatter by 0.12-0.38 px on renderer 2 (the rougher
#: edge at most 2.0 times the other) and 0.25-0.48 px on the real clip (at most 1.43
#: times).
ROUGH_PX = 0.45
#: ... when it is also this many times the other edge's.
ROUGH_RATIO = 2.0
#: An edge scattering more than this is refused whatever the other does, px.
ROUGH_MAX_PX = 1.5
#: Largest ripple of the filament's interior beside an edge (the median over the frame
#: groups' means, :func:`~flowtwin.vision.silhouette.interior_ripple`), as a fraction
#: of the edge's contrast, for which the silhouette is taken to be resolved from its
#: texture (module docstring, 4). Renderer 2, seeds 1-8 and 11-20, 90 frames: the clips
#: that read within 0.5 px in every frame ripple by 0.2-1.5 % (the real clip of [003]:
#: 0.4-1.4 %); 2.0 % reads 0.25 px off in the median, 2.2-2.3 % 0.2-0.9 px (seeds 16
#: and 19, 130 frames beyond 0.5 px), and the strongly striped 3.25-7.2 %.
RIPPLE_MAX = 0.018
#: Fewest frame groups (:class:`FrameGroups`) whose means may set the clip's blur and
#: limb shapes when the recording was coded by an inter-frame codec (module docstring,
#: 5): 6 groups, 48 frames at 8 per group.
MIN_GROUPS_INTER = 6
#: Height of the row bands of the frame-wide reference scan, rows.
REFERENCE_BAND_ROWS = 32
#: The ROI's width may differ from the filament's width elsewhere in the frame by this
#: many px or this fraction, whichever is larger (a filament's diameter changes little
#: over the ~10 mm a microscope sees).
REFERENCE_TOL_PX = 1.5
REFERENCE_TOL_FRACTION = 0.02
#: How far the gear's teeth reach beyond the contact radius: the bite (~0.1 mm) and a
#: margin for the knurl's depth, mm.
TOOTH_REACH_MM = 0.25

_REFUSED = int(Quality.WIDTH_INVALID | Quality.WIDTH_AMBIGUOUS)


def is_clean(scatter: tuple[float, float]) -> bool:
    """Whether two edges whose rows scatter by ``scatter`` px about their lines look like
    a silhouette (see the module docstring)."""
    rough, other = max(scatter), min(scatter)
    return not (rough > ROUGH_MAX_PX or (rough > ROUGH_PX and rough > ROUGH_RATIO * other))


def contact_rows(center_px: tuple[float, float], contact_radius_px: float, reach_px: float
                 ) -> tuple[float, float]:
    """Rows where a gear of contact radius ``R_c`` whose teeth reach ``R_c + δ`` covers
    the filament's edge: ``y_c ± √((R_c + δ)² − R_c²)``.

    Parameters
    ----------
    center_px
        Gear axis ``(x, y)``, px.
    contact_radius_px
        Distance from the axis to the filament's near edge, px.
    reach_px
        How far the teeth reach beyond it, ``δ``, px.

    Returns
    -------
    tuple of float
        First and last row of the zone, px.
    """
    r = contact_radius_px
    half = math.sqrt(max((r + reach_px) ** 2 - r * r, 0.0))
    return center_px[1] - half, center_px[1] + half


@dataclass
class FrameGroups:
    """Means of the ``before`` crop over groups of :data:`SHAPE_GROUP` consecutive frames
    whose edges stay put (module docstring, 1): the filament's texture moves with the
    material and averages out, its silhouette, the blur and the limb's shading do not.
    At most ``2·keep`` groups are kept (every other one dropped when there are more)."""

    size: int = SHAPE_GROUP
    keep: int = SHAPE_FRAMES
    means: list[npt.NDArray[np.float32]] = field(default_factory=list)
    _sum: npt.NDArray[np.float32] | None = None
    _count: int = 0
    _at: tuple[float, float] = (math.nan, math.nan)

    def add(self, crop: npt.NDArray[np.uint8],
            lines: tuple[tuple[float, float], tuple[float, float]]) -> None:
        """Add one frame's crop whose edge lines were found."""
        mid = 0.5 * (crop.shape[0] - 1)
        at = (lines[0][0] * mid + lines[0][1], lines[1][0] * mid + lines[1][1])
        if self._sum is not None and (self._sum.shape != crop.shape or max(
                abs(at[0] - self._at[0]), abs(at[1] - self._at[1])) > GROUP_SHIFT_PX):
            self.close()
        if self._sum is None:
            self._sum, self._count, self._at = crop.astype(np.float32), 1, at
        else:
            self._sum += crop
            self._count += 1
        if self._count >= self.size:
            self.close()

    def close(self) -> None:
        """End the present group (kept when it holds at least half a group)."""
        if self._sum is not None and 2 * self._count >= self.size:
            self.means.append(self._sum / np.float32(self._count))
            if len(self.means) > 2 * self.keep:
                self.means = self.means[::2]
        self._sum, self._count = None, 0


@dataclass
class ClipWidth:
    """Width measurement over a recording (see the module docstring).

    Parameters
    ----------
    roi
        The ``before`` ROI.
    expected_px
        Plausible widths, px (:func:`~flowtwin.vision.width.expected_width_px`).
    sigma_px, min_edge_dn_px
        Edge search parameters (:func:`~flowtwin.vision.width.measure_width_px`).
    blur_frames
        Frames fitted freely before the clip's blur is fixed.
    codec
        FOURCC of the recording's codec when it is an inter-frame codec
        (:data:`~flowtwin.vision.capture.INTER_FRAME_CODECS`), else ``None``
        (module docstring, 5).
    """

    roi: Roi
    expected_px: Sequence[tuple[float, float]] | None
    sigma_px: float = 0.7
    min_edge_dn_px: float = 3.0
    blur_frames: int = BLUR_FRAMES
    codec: str | None = None
    blur_px: float | None = None
    mix: tuple[float, float] | None = None
    #: Frames in the local line the widths were taken from (set by :meth:`finish`; 1: none).
    window_frames: int = 1
    _strip: npt.NDArray[np.uint8] | None = None
    _reference: tuple[float | None, tuple[int, ...]] | None = None
    _groups: FrameGroups = field(default_factory=FrameGroups)
    _stored: list[tuple[int, EdgeMeasurement]] = field(default_factory=list)
    _scatter: list[tuple[float, float]] = field(default_factory=list)
    _ripple: list[tuple[float, float]] = field(default_factory=list)
    _n_groups: int = 0

    def measure(self, crop: npt.NDArray[np.uint8]) -> EdgeMeasurement:
        """Width of one frame's ``before`` crop. Until the clip's blur is fixed, the
        silhouettes are fitted here (blur free); after, the frame's edges are found and
        its profiles taken, and the fit is left to :meth:`finish`, which fits all those
        frames in one vectorised pass (status ``"pending"`` until then)."""
        em = measure_width_px(crop, sigma_px=self.sigma_px,
                              min_edge_dn_px=self.min_edge_dn_px,
                              expected_px=self.expected_px, blur_px=self.blur_px,
                              fit=self.blur_px is None)
        if em.lines is not None:
            self._groups.add(crop, em.lines)
        return em

    def scan_frame(self, image: npt.NDArray[np.uint8]) -> None:
        """Keep the ROI's columns (±20 px) of the first frame whose edges were found, for
        :attr:`reference_px`."""
        if self._strip is None:
            x0, x1 = max(0, self.roi.x - 20), min(image.shape[1], self.roi.x1 + 20)
            self._strip = image[:, x0:x1].copy()

    @property
    def reference_px(self) -> float | None:
        """The filament's width elsewhere in the frame (:meth:`scan_frame`'s columns in
        bands of :data:`REFERENCE_BAND_ROWS` rows over the whole height; the bands whose
        edges are clean silhouettes give the reference, their median, when at least two
        agree), px; ``None`` without one. Worked out once, on first use (with the clip's
        blur once it is known)."""
        return self._scan_reference()[0]

    @property
    def reference_rows(self) -> tuple[int, ...]:
        """First rows of the bands that gave :attr:`reference_px`."""
        return self._scan_reference()[1]

    def _scan_reference(self) -> tuple[float | None, tuple[int, ...]]:
        if self._reference is not None:
            return self._reference
        self._reference = (None, ())
        if self._strip is None:
            return self._reference
        strip = self._strip
        starts = range(0, strip.shape[0] - REFERENCE_BAND_ROWS + 1, REFERENCE_BAND_ROWS)
        ems = [measure_width_px(strip[y0:y0 + REFERENCE_BAND_ROWS], sigma_px=self.sigma_px,
                                min_edge_dn_px=self.min_edge_dn_px,
                                expected_px=self.expected_px, blur_px=self.blur_px,
                                fit=self.blur_px is None) for y0 in starts]
        if self.blur_px is not None:
            # all bands' silhouettes in one pass at the clip's blur
            ems = refit_widths(ems, self.blur_px, REFERENCE_BAND_ROWS, self.expected_px)
        found = [(y0, em.width_px) for y0, em in zip(starts, ems, strict=True)
                 if em.ok and is_clean(em.edge_scatter_px)]
        if len(found) < 2:
            return self._reference
        widths = np.array([v for _, v in found])
        ref = float(np.median(widths))
        agree = np.abs(widths - ref) <= _tolerance(ref)
        if int(agree.sum()) >= 2:
            self._reference = (float(np.median(widths[agree])),
                               tuple(y for (y, _), a in zip(found, agree, strict=True) if a))
        return self._reference

    def record(self, row: int, em: EdgeMeasurement) -> None:
        """Note the measurement of row ``row``; once :attr:`blur_frames` frames were
        fitted freely, fix the clip's blur (their median)."""
        self._scatter.append(em.edge_scatter_px)
        if em.silhouette is None or not math.isfinite(em.blur_px):
            return
        # keep what a refit needs, not the per-row diagnostics
        empty = np.zeros(0)
        self._stored.append((row, replace(em, row_left_px=empty, row_right_px=empty,
                                          row_used=np.zeros(0, bool))))
        if self.blur_px is None and len(self._stored) >= self.blur_frames:
            self.blur_px = float(np.median([e.blur_px for _, e in self._stored]))

    def _refit_all(self, rows: RowLog) -> None:
        """The clip's blur (if not yet fixed) and limb shapes (medians over all frames),
        and every frame refitted with them."""
        if not self._stored:
            return
        if self.blur_px is None:
            self.blur_px = float(np.median([e.blur_px for _, e in self._stored]))
        sils = self._shape_silhouettes()
        self._n_groups = len(sils)
        if len(sils) < 2:
            # too few frame groups: single frames, each with its own fit (limb shapes
            # free) at the running blur
            todo = [i for i, (_, em) in enumerate(self._stored) if em.status == "pending"]
            fitted = refit_widths([self._stored[i][1] for i in todo], self.blur_px,
                                  self.roi.h, self.expected_px)
            for i, em in zip(todo, fitted, strict=True):
                self._stored[i] = (self._stored[i][0], em)
            ok = [em for _, em in self._stored if em.ok and em.silhouette is not None]
            pick = ok[::max(1, len(ok) // SHAPE_FRAMES)][:SHAPE_FRAMES]
            sils = [em.silhouette for em in pick if em.silhouette is not None]
        if sils:
            self.blur_px, self.mix = clip_model([sl.profiles for sl in sils],
                                                [(sl.left, sl.right) for sl in sils],
                                                self.blur_px)
        refits = refit_widths([em for _, em in self._stored], self.blur_px, self.roi.h,
                              self.expected_px, self.mix)
        for (row, _), new in zip(self._stored, refits, strict=True):
            if new.ok:
                rows.width[row] = new.width_px
                rows.left[row] = new.left_px + self.roi.x
                rows.right[row] = new.right_px + self.roi.x
                rows.flags[row] &= ~_REFUSED
            else:
                _refuse_row(rows, row)
        self._stored.clear()

    def _shape_silhouettes(self) -> list[Silhouette]:
        """The silhouettes of the frame groups' mean crops (:class:`FrameGroups`), fitted
        at the running blur, for the clip's blur and limb shapes."""
        self._groups.close()
        if self.blur_px is None:
            return []
        found = [measure_width_px(mean, sigma_px=self.sigma_px,
                                  min_edge_dn_px=self.min_edge_dn_px,
                                  expected_px=self.expected_px, blur_px=self.blur_px,
                                  fit=False) for mean in self._groups.means]
        fitted = refit_widths(found, self.blur_px, self.roi.h, self.expected_px)
        ok = [(mean, em) for mean, em in zip(self._groups.means, fitted, strict=True)
              if em.ok and em.silhouette is not None and em.lines is not None]
        self._ripple = [interior_ripple(mean, np.flatnonzero(em.row_used), em.lines,
                                        em.silhouette, 0.5 * em.width_px)
                        for mean, em in ok if em.silhouette is not None and em.lines]
        return [em.silhouette for _, em in ok if em.silhouette is not None]

    def finish(self, rows: RowLog, gear_center_px: tuple[float, float] | None,
               mm_per_px: float | None) -> str | None:
        """Refit every frame with the clip's blur and limb shapes, then apply the
        clip-level refusals.

        Parameters
        ----------
        rows
            The pipeline's rows (widths and flags are changed in place).
        gear_center_px
            Gear axis, if known.
        mm_per_px
            Image scale, if known (for the teeth's reach).

        Returns
        -------
        str or None
            Why every width was refused (None if they were not).
        """
        self._refit_all(rows)
        note = self.rough_edges()
        if note is None:
            note = self.striped()
        if note is None:
            note = self.against_reference(rows)
        if note is None and gear_center_px is not None:
            note = self._in_contact_zone(rows, gear_center_px, mm_per_px)
        if note is None:
            note = self.too_few_groups(rows)
        if note is not None:
            skipped = int(Quality.BLANK | Quality.DUPLICATE)
            for row in range(len(rows.width)):
                if not rows.flags[row] & skipped:
                    _refuse_row(rows, row)
            return note
        self.window_frames = _follow_neighbours(rows, self.roi.h)
        return None

    def rough_edges(self) -> str | None:
        """Why the edges are not a clean silhouette over the clip (None if they are)."""
        sc = np.array([s for s in self._scatter if math.isfinite(s[0] + s[1])])
        if sc.size == 0:
            return None
        left, right = (float(v) for v in np.median(sc, axis=0))
        rough, other = max(left, right), min(left, right)
        name = "left" if left >= right else "right"
        if not is_clean((left, right)):
            return (f"the {name} edge is not a clean silhouette: its rows scatter by "
                    f"{rough:.2f} px about a straight line (median over {len(sc)} frames; "
                    f"the other edge {other:.2f} px) - gear teeth over the edge, teeth "
                    "marks in it or marks on the filament along it; place the before ROI "
                    "where the filament runs clear")
        return None

    def striped(self) -> str | None:
        """Why the silhouettes cannot be told from the texture next to them (None if
        they can, or without frame groups): a ripple of the interior above
        :data:`RIPPLE_MAX` of the contrast beside either edge."""
        rp = np.array([r for r in self._ripple if math.isfinite(r[0] + r[1])])
        if rp.size == 0:
            return None
        left, right = (float(v) for v in np.median(rp, axis=0))
        worst, name = max((left, "left"), (right, "right"))
        if worst <= RIPPLE_MAX:
            return None
        return (f"the filament's interior beside its {name} edge is striped: it departs "
                f"from a smoothly shaded cylinder by {100 * worst:.1f} % of the edge's "
                f"contrast (median over {len(rp)} groups of frames; at most "
                f"{100 * RIPPLE_MAX:.1f} % allowed) - stripes along the filament do not "
                "move in the image and, foreshortened at the limb, cannot be told from "
                "its edge; the width could be off by more than half a pixel")

    def too_few_groups(self, rows: RowLog) -> str | None:
        """Why the clip's blur and limb shapes are not determined under its codec (None
        if they are, or if the codec codes every frame on its own): fewer than
        :data:`MIN_GROUPS_INTER` frame groups (module docstring, 5)."""
        if self.codec is None or self._n_groups >= MIN_GROUPS_INTER:
            return None
        if not np.isfinite(np.asarray(rows.width, dtype=np.float64)).any():
            return None
        return (f"only {self._n_groups} groups of {SHAPE_GROUP} frames with the filament's "
                f"edges: under the {self.codec} codec's compression the clip's blur and "
                f"limb shapes need at least {MIN_GROUPS_INTER} "
                f"({MIN_GROUPS_INTER * SHAPE_GROUP} frames) - it predicts each frame from "
                "earlier ones, so a short clip's frames share its error at the edge, and "
                "the width could be off by more than half a pixel; record a longer clip, "
                "or losslessly")

    def against_reference(self, rows: RowLog) -> str | None:
        """Why the ROI's width is not the filament's elsewhere in the frame (None if it
        is, or if there is no reference)."""
        width = np.asarray(rows.width)
        width = width[np.isfinite(width)]
        if self.reference_px is None or width.size == 0:
            return None
        here = float(np.median(width))
        if abs(here - self.reference_px) <= _tolerance(self.reference_px):
            return None
        bands = ", ".join(f"{y}-{y + REFERENCE_BAND_ROWS}" for y in self.reference_rows)
        return (f"the width in the before ROI ({here:.1f} px) is not the filament's width "
                f"elsewhere in the frame ({self.reference_px:.1f} px where its edges are "
                f"clean, rows {bands}): something covers an edge in the ROI (the gear's "
                "teeth?); place the before ROI where the filament runs clear")

    def _in_contact_zone(self, rows: RowLog, center: tuple[float, float],
                         mm_per_px: float | None) -> str | None:
        left, right = np.asarray(rows.left), np.asarray(rows.right)
        ok = np.isfinite(left) & np.isfinite(right)
        if not ok.any():
            return None
        near = np.where(np.abs(left[ok] - center[0]) <= np.abs(right[ok] - center[0]),
                        left[ok], right[ok])
        r_c = float(np.median(np.abs(near - center[0])))
        reach = TOOTH_REACH_MM / mm_per_px if mm_per_px else 0.03 * r_c
        y0, y1 = contact_rows(center, r_c, reach)
        if self.roi.y < y1 and self.roi.y1 > y0:
            return (f"the before ROI (rows {self.roi.y}-{self.roi.y1}) reaches the gear's "
                    f"contact zone (rows {y0:.0f}-{y1:.0f}: gear axis at ({center[0]:.0f}, "
                    f"{center[1]:.0f}), contact radius {r_c:.0f} px): the teeth cover the "
                    "filament's edge there; place the before ROI above or below it")
        return None


def _follow_neighbours(rows: RowLog, roi_height_px: int) -> int:
    """Every frame's width the local line through its neighbours' (module docstring, 6;
    :func:`~flowtwin.vision.width_series.local_line`), its edges moved symmetrically
    about their own centre by the same factor as its width (the edges are columns, the
    width is across the tilted filament).

    The window holds at most :data:`~flowtwin.vision.width_series.WINDOW_FRAMES` frames
    and spans no more than the filament travels through the ROI's height (the length the
    ROI already averages the width over) at the clip's fast speed (the 95th percentile of
    the filament's steps); without a filament speed, no window. Returns the frames the
    lines were fitted over (1: none).
    """
    width = np.asarray(rows.width, dtype=np.float64)
    measured = int(np.count_nonzero(np.isfinite(width)))
    if measured < MIN_FRAMES:
        return 1
    window = neighbour_frames(rows.t, rows.fil, rows.fil_span, roi_height_px)
    if window < 3:
        return 1
    left = np.asarray(rows.left, dtype=np.float64)
    right = np.asarray(rows.right, dtype=np.float64)
    centre, half = 0.5 * (left + right), 0.5 * (right - left)
    line = local_line(width, window)
    with np.errstate(invalid="ignore", divide="ignore"):
        half = half * (line / width)
    rows.width[:] = line.tolist()
    rows.left[:] = (centre - half).tolist()
    rows.right[:] = (centre + half).tolist()
    return min(window, measured)


def _tolerance(width_px: float) -> float:
    return max(REFERENCE_TOL_PX, REFERENCE_TOL_FRACTION * width_px)


def _refuse_row(rows: RowLog, row: int) -> None:
    rows.width[row] = math.nan
    rows.left[row] = math.nan
    rows.right[row] = math.nan
    rows.flags[row] |= _REFUSED
