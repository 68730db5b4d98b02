"""What to measure and how, for each ``flowtwin calibrate`` command.

The instructions a user needs before a fit can work: which pattern or test to run, what
to measure with what, and the file format. The CLI shows them as ``--help`` (plain text:
no square brackets, which the help renderer would take for markup); docs/calibration.md
says the same at more length.
"""

from __future__ import annotations

__all__ = ["ADAPTIVE_HELP", "FIT_K_HELP", "FIT_SLIP_HELP", "FROM_IMAGE_HELP", "PATTERN_HELP",
           "PATTERN_KIND_HELP", "STRAND_HELP", "VISCOSITY_HELP"]

PATTERN_HELP = """Write a calibration test pattern as G-code for your firmware.

One command per pattern kind (flowtwin calibrate pattern KIND --help for
its options): kline, chevron and tower test the advance factor K; flow
the extrusion multiplier; maxflow the maximum volumetric speed; flowline
writes a line for a measured lag fit.

Every extrusion uses the slicer bead A = w*h - (1 - pi/4)*h^2. Unless
--no-check, the file is read back and planned with flowtwin's reader
and planner for --printer, and the test speeds are checked to be
reached (a warning names every move that falls short).
"""

#: What each pattern kind prints and how to read it (the help of its command).
PATTERN_KIND_HELP = {
    "kline": """K-factor lines (Marlin style).

Each line is 20 mm slow, 40 mm fast, 20 mm slow, one advance factor K
per line, front to back. Where the speed steps up and down, pick the K
whose line keeps an even width.
""",
    "chevron": """Ellis-style chevrons.

Nested 90-degree corners, one K per whole chevron, left to right. Pick
the chevron with a sharp apex and no gap before it.
""",
    "tower": """A pressure-advance tower.

A square tower with K = k_start + k_step_per_mm * z. Measure with
calipers the height z of the best corners; K follows from it.
""",
    "flow": """Extrusion-multiplier blocks.

Solid blocks, front left first. Pick the block with a closed, flat
top; multiply your flow setting by its value.
""",
    "maxflow": """Lines of rising volumetric flow (maximum volumetric speed).

Lines of rising flow (mm3/s), front to back. The last line that is
still full and even is your maximum volumetric speed.
""",
    "flowline": """One line alternating v/4 and v for a target flow.

One line per K if --k-start/--k-end/--k-step are given. Measure its
width along the line (microscope, scanner, camera) every ~0.5 mm for a
lag fit.
""",
}

VISCOSITY_HELP = """Fit a viscosity law to a temperature sweep; write a viscosity fragment.

What to measure: extrude into air (no bed) at ONE constant volumetric
flow (e.g. 5 mm3/s) while stepping the nozzle temperature (e.g. 190 to
240 C in 5 C steps, 3 repeats each); at each step wait until the force
is steady, then record it.

DATA.csv has a header line naming its columns (# starts a comment):
temp_c (melt temperature, C; required) and ONE of
feed_force_n with flow_mm3_s (steady force on the filament, load cell),
slip_pct with flow_mm3_s (steady drive slip, %; needs --drive),
viscosity_pa_s (viscosity measured elsewhere, Pa*s).

A force becomes a viscosity through the hot end's Hagen-Poiseuille
resistance (--hotend); a slip becomes a force through the drive's slip
law s = k_p + s'*F. The fragment holds the law's parameters with their
1-sigma errors as comments: paste it into a material profile in place
of its viscosity table.
"""

STRAND_HELP = """Fit the strand shape (tractrix, parabola, catenary) to profile points.

What to measure: film from the side (or section) the strand between
the nozzle and the bed while printing a straight line at constant
speed. DATA.csv has the columns x_mm (distance behind the nozzle axis;
the strand trails towards +x) and z_mm (height above the layer below).

Give --height-mm, the nozzle height above the layer below. The points
must reach past where the strand meets the bed. The fragment's lag_mm
is how far behind the nozzle the strand reaches the bed.
"""

ADAPTIVE_HELP = """Build OrcaSlicer's adaptive pressure-advance table from measured K.

What to measure: run a K test (kline or chevron pattern) at several
print speeds (e.g. 50, 100, 150, 200 mm/s) and accelerations (e.g.
1000, 2000, 4000 mm/s2), two or more speeds per acceleration, and note
the best K of each test.

MEASUREMENTS.csv has the columns k_s (best K, s), accel_mm_s2 (whole
number) and flow_mm3_s, or instead of flow_mm3_s the three columns
speed_mm_s, line_width_mm, layer_height_mm (flow = bead area * speed);
optional k_err_s (1-sigma error of k_s: repeats are weighted by
1/error^2). fit-k --append-to writes exactly such rows.

The output has one "K,flow,accel" line per measurement: paste it into
OrcaSlicer's filament setting "Adaptive pressure advance measurements".
Between measurements K is interpolated (monotone cubic in flow, then
in acceleration) and held at the edge values outside them.
"""

FIT_K_HELP = """Fit the lag K (the advance factor to set) to a width profile of a test line.

What to measure: print a test line with speed changes at a known advance
factor (one K-line: pattern kline --k-start K --k-end K; K = 0 shows the
lag best). Measure the bead width along it every 0.2-0.5 mm from its
start, in the print direction (microscope on a stage, a 600+ dpi scan, a
photo with a scale).

PROFILE.csv columns: position_mm (distance from the line's start, mm),
width_mm (bead width, mm); optional gcode_line (G-code line of the first
move of the test line a row belongs to: several lines in one file).

Which line: --gcode FILE with --gcode-line N (the line's first extruding
move; repeat for several), or without --gcode a K-line generated from
the options (--k-la, the advance factor it was printed with; speeds,
lengths, bead, --accel) for --machine's firmware.

The twin (the --machine printer's planner, the firmware's advance and
the lag with no backflow) predicts the width along the line for a lag
K; least squares gives K +- 1 sigma (--fit-dead-time, --fit-gain: also a
dead time and a flow gain). Ends within --end-margin are left out. -o
writes a pressure_advance printer-profile fragment (k_s = K);
--append-to adds a k_s,k_err_s,flow_mm3_s,accel_mm_s2 row to a file for
adaptive-pa (one run per flow and acceleration).
"""

FROM_IMAGE_HELP = """Read the advance factor from a photo or scan of a printed line pattern.

--pattern names what you printed: kline (flowtwin's), marlin (Marlin's
K-factor generator), prusa (Prusa's linear-advance lines), orca
(OrcaSlicer's PA line), orca-legacy (OrcaSlicer 1.x / Bambu Studio),
pa-camera (PressureAdvanceCamera's framed lines) or chevron (flowtwin's
chevrons: --walls, --arm-length, --gap, --layers as printed).
Give the K range and any setting you changed from the tool's defaults
(--k-start, --k-end, --k-step, speeds, lengths, --pitch) and the
--machine it printed on.

What to measure: photograph the whole pattern with a margin, roughly square on,
in focus, without a flash reflection on the lines. Beads may be lighter
or darker than the sheet (found from the image; --polarity to force);
textured and glossy sheets, labels and numbers beside the lines are fine.
No tick marks are needed: the lines' ends and spacing give the frame and
the scale, the pattern's marks (prime lines, numbers, reference marks)
or the widths give its direction. A print scanned face down: --view
mirrored. A scan's resolution (--dpi) fixes the width scale.

Each line is scored by how even it stays after its speed changes (the
most even line; K where the errors cross zero, Tronvoll et al. 2019
Table II) and the twin's lag is fitted to all lines (K +- 1 sigma);
-o writes the [pressure_advance] fragment, --annotate an annotated copy
of the photo, --json everything (k_s, k_err_s, k_best_line_s, scores).

A photo that cannot support an answer is refused with the reason: blur,
too few lines, lines cut by the frame, a line count that is not the
pattern's, a direction neither the marks nor the widths decide; and an
answer the photo does not support: the best line at an end of the range,
a best line and lag that disagree, or a best line only the smallest
score picks when no lag could be fitted.
"""

FIT_SLIP_HELP = """Fit a drive's slip law from test-stand records; write a drive fragment.

What to measure: on a filament-drive test stand (Nienhaus 2021), for each
pinch force (10-150 N) and feed speed (0.5-15 mm/s), 3+ repeats: drive
at the set speed, raise the process force at 4 N/s until the filament
stalls, release; record time, encoder speed, feed force and pinch force
at 50 samples/s. RECORDS.csv is the test stand's schema 1
(docs/teststand.md; teststand simulate writes the same format).

The evaluation is flowtwin teststand's (slip regression per record,
Eq. 6 over pinch force, Eq. 8 over speed at 80-130 N, the
maximum-force fit). The fragment holds k_p_pct (mean regression offset)
and the slip_overrides table (k_s, k_inf and, if significant, a, b, c) with
1-sigma errors: paste it into the drive profile.
"""

