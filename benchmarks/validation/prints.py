"""The validation prints: what is sliced, by which slicer, with which settings, for which
printer — and whether a print belongs to the *dev* set (may be looked at while developing)
or to a *check* set (run only to report, never tuned on): ``check`` since session 5,
``check2`` (four more models: a thin-walled clip, a knurled knob, an arch, a perforated
plate) since session 12, ``check3`` (a J hook, a tapered cup, a lattice block, a hex nut)
since session 13, ``check4`` (a spool, a comb of thin fins, a honeycomb panel, a wave wall),
``check5`` (a tube bundle, a thin cross, a stepped pyramid, a slotted plate) since
session 14, and ``check6`` (a twisted prism, a peg board, a bridge on two pillars, a vent
grille) since session 15.

Every print is a model of ``models/`` (OpenSCAD) sliced by one of Debian's slicers
(``prusa-slicer`` 2.5 with its Arachne or classic perimeters, ``slic3r`` 1.3,
``CuraEngine`` 4.13) with speeds of 40–300 mm/s, accelerations of 500–5000 mm/s², layers
of 0.1–0.3 mm, relative or absolute E, and compensated for a Klipper printer (a
``printer.cfg`` written from the row's limits, with an E3D Volcano) or a Marlin one (an
E3D V6). Each slicer is held to the hot end's maximum volumetric flow at the print's layer
height (``flowtwin limits``: the flow at which 5 % is lost to slip), as a user sets up a
slicer for a hot end (PrusaSlicer's and Slic3r's ``max_volumetric_speed``; CuraEngine has
none: its speeds are capped to that flow for its line width): the requested speeds reach
the fast end of the range where the lines are thin. The dev and check sets use different
models and different settings.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PRINTS", "SPLITS", "Print"]


@dataclass(frozen=True, slots=True)
class Print:
    """One validation print.

    Attributes
    ----------
    name
        File stem.
    split
        ``"dev"``, ``"check"``, ``"check2"`` … ``"check6"``.
    model
        OpenSCAD model in ``models/`` (without ``.scad``).
    slicer
        ``"prusa-arachne"``, ``"prusa-classic"``, ``"slic3r"`` or ``"cura"``.
    layer_mm
        Layer height, mm.
    wall_mm_s, infill_mm_s
        Perimeter and infill speed, mm/s (outer walls, solid and top infill are set from
        them the way each slicer's defaults relate them).
    accel_mm_s2
        Print acceleration the slicer writes, mm/s².
    relative_e
        Relative E (``M83``) instead of absolute.
    printer
        ``"klipper"`` (a ``printer.cfg`` with ``max_velocity`` ``velocity_mm_s``,
        ``max_accel`` ``accel_mm_s2`` and ``square_corner_velocity`` ``scv_mm_s``), or a
        Marlin set-up: ``"marlin-mk25"`` (the twin's Prusa MK2.5, ``tronvoll2019``) or
        ``"marlin-generic"`` (Marlin 2 stock limits).
    velocity_mm_s, scv_mm_s
        Klipper's ``max_velocity`` and ``square_corner_velocity``.
    """

    name: str
    split: str
    model: str
    slicer: str
    layer_mm: float
    wall_mm_s: float
    infill_mm_s: float
    accel_mm_s2: float
    relative_e: bool
    printer: str
    velocity_mm_s: float = 300.0
    scv_mm_s: float = 5.0


def _p(split: str, model: str, slicer: str, layer: float, wall: float, infill: float,
       accel: float, rel: bool, printer: str, velocity: float = 300.0,
       scv: float = 5.0) -> Print:
    name = (f"{split}-{model}-{slicer}-{layer:g}mm-{wall:g}-{infill:g}mms-a{accel:g}-"
            f"{'rel' if rel else 'abs'}-{printer}")
    return Print(name, split, model, slicer, layer, wall, infill, accel, rel, printer,
                 velocity, scv)


PRINTS: tuple[Print, ...] = (
    # ---- dev: may be looked at while developing ----------------------------------------
    _p("dev", "cube", "prusa-arachne", 0.2, 150, 250, 3000, True, "klipper", 300, 5),
    _p("dev", "ring", "prusa-classic", 0.1, 40, 60, 1000, False, "marlin-mk25"),
    _p("dev", "star", "slic3r", 0.3, 80, 120, 1500, False, "klipper", 200, 5),
    _p("dev", "wedge", "cura", 0.2, 60, 80, 2000, False, "marlin-generic"),
    _p("dev", "cube", "cura", 0.3, 150, 200, 5000, True, "klipper", 300, 8),
    _p("dev", "ring", "slic3r", 0.2, 150, 250, 3000, True, "marlin-generic"),
    _p("dev", "star", "prusa-arachne", 0.15, 100, 150, 2000, False, "marlin-mk25"),
    _p("dev", "wedge", "prusa-arachne", 0.25, 50, 70, 800, True, "klipper", 150, 5),
    _p("dev", "cube", "slic3r", 0.1, 40, 50, 500, False, "marlin-mk25"),
    _p("dev", "ring", "cura", 0.15, 150, 250, 3000, False, "klipper", 300, 5),
    _p("dev", "star", "cura", 0.25, 40, 60, 1000, True, "marlin-generic"),
    _p("dev", "wedge", "prusa-classic", 0.3, 200, 300, 4000, False, "klipper", 300, 5),
    # ---- check: run only to report ---------------------------------------------------------
    _p("check", "gear", "prusa-arachne", 0.2, 120, 200, 2500, False, "klipper", 250, 5),
    _p("check", "bracket", "cura", 0.2, 70, 100, 1500, True, "marlin-mk25"),
    _p("check", "tower", "slic3r", 0.15, 60, 90, 1200, True, "klipper", 200, 4),
    _p("check", "dome", "prusa-classic", 0.25, 100, 160, 3000, True, "marlin-generic"),
    _p("check", "gear", "cura", 0.12, 50, 70, 800, False, "klipper", 150, 5),
    _p("check", "bracket", "prusa-arachne", 0.3, 180, 280, 5000, True, "klipper", 300, 6),
    _p("check", "tower", "prusa-classic", 0.1, 45, 60, 700, False, "marlin-mk25"),
    _p("check", "dome", "slic3r", 0.2, 120, 180, 2000, False, "klipper", 250, 5),
    _p("check", "gear", "slic3r", 0.28, 160, 240, 3500, True, "marlin-generic"),
    _p("check", "bracket", "slic3r", 0.12, 40, 55, 600, False, "marlin-mk25"),
    _p("check", "tower", "cura", 0.25, 200, 300, 4000, False, "klipper", 300, 5),
    _p("check", "dome", "cura", 0.18, 90, 140, 2500, True, "marlin-generic"),
    # ---- check2 (session 12): new models and settings, chosen before any was run --------
    _p("check2", "clip", "prusa-classic", 0.2, 60, 100, 1500, True, "klipper", 200, 5),
    _p("check2", "knob", "cura", 0.15, 40, 60, 800, False, "marlin-mk25"),
    _p("check2", "arch", "slic3r", 0.25, 100, 150, 2500, True, "marlin-generic"),
    _p("check2", "plate", "prusa-arachne", 0.3, 150, 220, 4000, False, "klipper", 300, 5),
    _p("check2", "clip", "cura", 0.12, 80, 120, 2000, False, "klipper", 250, 5),
    _p("check2", "knob", "prusa-arachne", 0.25, 120, 180, 3000, True, "marlin-generic"),
    _p("check2", "arch", "prusa-classic", 0.1, 45, 70, 700, False, "marlin-mk25"),
    _p("check2", "plate", "slic3r", 0.2, 50, 80, 1000, True, "klipper", 150, 5),
    _p("check2", "clip", "slic3r", 0.3, 180, 260, 5000, False, "marlin-generic"),
    _p("check2", "knob", "prusa-classic", 0.2, 200, 300, 4000, True, "klipper", 300, 5),
    _p("check2", "arch", "cura", 0.2, 150, 250, 3000, True, "klipper", 300, 8),
    _p("check2", "plate", "cura", 0.25, 60, 90, 1200, False, "marlin-mk25"),
    # ---- check3 (session 13): new models and settings, chosen before any was run --------
    _p("check3", "hook", "prusa-arachne", 0.2, 90, 140, 2000, True, "klipper", 250, 5),
    _p("check3", "cup", "cura", 0.1, 40, 55, 600, False, "marlin-mk25"),
    _p("check3", "lattice", "slic3r", 0.3, 120, 180, 3500, True, "klipper", 300, 6),
    _p("check3", "nut", "prusa-classic", 0.15, 70, 110, 1500, False, "marlin-generic"),
    _p("check3", "hook", "cura", 0.25, 160, 260, 4500, True, "klipper", 300, 5),
    _p("check3", "cup", "prusa-classic", 0.3, 100, 150, 2500, True, "klipper", 250, 8),
    _p("check3", "lattice", "prusa-arachne", 0.12, 50, 70, 900, False, "marlin-mk25"),
    _p("check3", "nut", "slic3r", 0.2, 140, 220, 3000, False, "klipper", 300, 5),
    _p("check3", "hook", "slic3r", 0.15, 45, 65, 800, False, "marlin-generic"),
    _p("check3", "cup", "prusa-arachne", 0.25, 200, 300, 5000, False, "klipper", 300, 5),
    _p("check3", "lattice", "cura", 0.2, 80, 120, 2000, True, "marlin-generic"),
    _p("check3", "nut", "cura", 0.3, 60, 90, 1200, True, "klipper", 200, 4),
    # ---- check4 (session 14): new models and settings, chosen before any was run --------
    _p("check4", "spool", "prusa-arachne", 0.2, 110, 180, 2500, True, "klipper", 250, 5),
    _p("check4", "comb", "cura", 0.2, 100, 150, 3000, False, "klipper", 300, 5),
    _p("check4", "honeycomb", "slic3r", 0.25, 70, 100, 1500, True, "marlin-generic"),
    _p("check4", "wave", "prusa-classic", 0.15, 50, 80, 1000, False, "marlin-mk25"),
    _p("check4", "spool", "cura", 0.15, 60, 90, 1500, True, "marlin-generic"),
    _p("check4", "comb", "prusa-classic", 0.3, 150, 250, 4000, True, "klipper", 300, 6),
    _p("check4", "honeycomb", "cura", 0.25, 120, 200, 3500, True, "klipper", 250, 5),
    _p("check4", "wave", "slic3r", 0.2, 130, 200, 2500, False, "klipper", 300, 5),
    _p("check4", "spool", "slic3r", 0.1, 40, 55, 700, False, "marlin-mk25"),
    _p("check4", "comb", "prusa-arachne", 0.12, 45, 65, 800, False, "marlin-generic"),
    _p("check4", "honeycomb", "prusa-arachne", 0.3, 180, 280, 5000, False, "klipper", 300, 8),
    _p("check4", "wave", "cura", 0.3, 90, 140, 2000, True, "marlin-mk25"),
    # ---- check5 (session 14, later): new models and settings, chosen before any was run --
    _p("check5", "tubes", "cura", 0.2, 120, 180, 3000, True, "klipper", 300, 5),
    _p("check5", "cross", "prusa-arachne", 0.25, 150, 250, 4000, False, "klipper", 300, 5),
    _p("check5", "steps", "slic3r", 0.15, 60, 90, 1200, True, "marlin-generic"),
    _p("check5", "slots", "prusa-classic", 0.2, 80, 120, 2000, False, "marlin-mk25"),
    _p("check5", "tubes", "prusa-classic", 0.3, 200, 300, 5000, True, "klipper", 300, 8),
    _p("check5", "cross", "cura", 0.12, 50, 70, 800, False, "marlin-mk25"),
    _p("check5", "steps", "prusa-arachne", 0.2, 100, 160, 2500, True, "klipper", 250, 5),
    _p("check5", "slots", "cura", 0.25, 70, 110, 1500, True, "marlin-generic"),
    _p("check5", "tubes", "slic3r", 0.1, 40, 60, 600, False, "marlin-mk25"),
    _p("check5", "cross", "slic3r", 0.3, 130, 200, 3000, True, "klipper", 300, 6),
    _p("check5", "steps", "cura", 0.3, 160, 260, 4500, False, "klipper", 300, 5),
    _p("check5", "slots", "prusa-arachne", 0.15, 45, 70, 1000, False, "marlin-generic"),
    # ---- check6 (session 15): new models and settings, chosen before any was run --------
    _p("check6", "twist", "prusa-classic", 0.2, 90, 140, 2000, True, "klipper", 250, 5),
    _p("check6", "pegs", "cura", 0.15, 60, 90, 1200, False, "marlin-mk25"),
    _p("check6", "bridge", "slic3r", 0.25, 110, 170, 3000, False, "klipper", 300, 5),
    _p("check6", "vent", "prusa-arachne", 0.2, 70, 110, 1500, True, "marlin-generic"),
    _p("check6", "twist", "cura", 0.28, 170, 260, 4500, True, "klipper", 300, 6),
    _p("check6", "pegs", "prusa-arachne", 0.3, 150, 230, 4000, False, "klipper", 300, 5),
    _p("check6", "bridge", "prusa-classic", 0.12, 45, 65, 800, False, "marlin-mk25"),
    _p("check6", "vent", "slic3r", 0.15, 120, 180, 2500, True, "klipper", 250, 5),
    _p("check6", "twist", "slic3r", 0.1, 40, 55, 600, False, "marlin-generic"),
    _p("check6", "pegs", "slic3r", 0.2, 80, 120, 2000, True, "marlin-generic"),
    _p("check6", "bridge", "cura", 0.2, 60, 100, 1500, True, "klipper", 200, 4),
    _p("check6", "vent", "cura", 0.25, 130, 200, 3000, False, "marlin-mk25"),
)

#: The splits, in the order they were made.
SPLITS: tuple[str, ...] = tuple(dict.fromkeys(p.split for p in PRINTS))
