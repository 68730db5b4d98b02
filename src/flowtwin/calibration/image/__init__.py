"""Reading photos and scans of printed advance-factor line patterns.

One concept per module (OpenCV is imported only here, never by the pattern code):

* :mod:`.layouts` — the line patterns people print (flowtwin's ``kline``, Marlin's
  K-factor test, Prusa's linear-advance lines, OrcaSlicer's PA line, old and new), each
  with its published geometry and defaults, written as G-code for the twin;
* :mod:`.signal` — the bead signal: polarity (beads lighter or darker than the sheet)
  decided from the image, lighting flattened, the sheet's texture suppressed;
* :mod:`.detect` — the long parallel lines of the pattern found in the bead signal;
* :mod:`.register` — found lines matched to the layout's lines without tick marks (line
  ends and spacing give frame and scale; the layout's other marks, or the physics, give
  the reading direction), and the bed → image homography;
* :mod:`.quality` — the checks that make a photo refuse an answer (blur, lines cut by the
  frame, too few lines);
* :mod:`.analyse` — widths, per-line scores and the twin's lag fit;
* :mod:`.annotate` — the annotated copy of the photo;
* :mod:`.photosynth` — an independent renderer of photographic conditions (validation).

The older tick-based reader of flowtwin's ``kline`` scans and its helpers live here too:
:mod:`.kimage` (``analyse_kline_image``), :mod:`.linefind` (lines and registration by
ticks), :mod:`.beadwidth` (bead width across a straightened line) and :mod:`.twin_render`
(known-answer images rendered from the twin). Images are loaded by
:mod:`flowtwin.vision.loader`, as in vision.
"""
