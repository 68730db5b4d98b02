"""The firmware kinds flowtwin models, and what each one is.

Every difference between firmwares that flowtwin knows is a property of :class:`Firmware`
(read from one table, :data:`_TRAITS`) or a function of :mod:`flowtwin.firmware` that
dispatches on those properties:

==================  =======  ==============  =====================================  ===========
firmware            planner  advance         advance command                        M220/M221 S
==================  =======  ==============  =====================================  ===========
``klipper``         Klipper  smoothed        ``SET_PRESSURE_ADVANCE ADVANCE=``      float
``marlin``          Marlin   linear advance  ``M900 K``                             integer
``reprapfirmware``  Marlin   within moves    ``M572 D0 S``                          not modelled
``prusa``           Marlin   smoothed        ``M572 S [W]``                         not modelled
``repetier``        Marlin   linear advance  ``M900 K``                             not modelled
==================  =======  ==============  =====================================  ===========

Klipper's advance command takes ``SMOOTH_TIME=`` too; Klipper sets the acceleration with
``SET_VELOCITY_LIMIT ACCEL=``, the others with ``M204 P T``.

* ``prusa`` is Prusa's 32-bit "Buddy" firmware (MK4, MK3.9, XL, MINI, Core One), whose
  ``M572`` takes ``S`` (advance) and ``W`` (smoothing window) and no ``D``. The 8-bit
  Prusa-Firmware of the MK3S and MK2.5 is a Marlin fork with Marlin's ``M900 K``: describe
  those printers as ``marlin``.
* ``repetier`` (Repetier-Firmware; the RF1000 of [003] runs Conrad's fork of it) is planned
  with the Marlin-style planner and given Marlin's linear advance and ``M900``: flowtwin
  has no model of Repetier's own advance, and its patterns for it are Marlin's.
* The planner family decides which limits a printer profile carries (Klipper's
  ``[limits]`` or the per-axis ``[marlin]`` table) and which planner runs.
* Adding a firmware: a member here, one row of :data:`_TRAITS`, and, if it speaks a new
  advance or acceleration syntax, a branch in :mod:`flowtwin.firmware.advance`;
  ``tests/firmware`` enumerates the members and checks every consumer handles each one.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from flowtwin.errors import ProfileError

__all__ = ["AdvanceAlgorithm", "Firmware", "PaSyntax", "PlannerFamily"]


class PlannerFamily(StrEnum):
    """Which look-ahead planner a firmware runs (:mod:`flowtwin.planner`)."""

    KLIPPER = "klipper"  #: Klipper's trapezoid generator (:mod:`flowtwin.planner.klipper`)
    MARLIN = "marlin"    #: Marlin 2.x and its relatives (:mod:`flowtwin.planner.marlin`)


class AdvanceAlgorithm(StrEnum):
    """How a firmware applies its pressure advance (:mod:`flowtwin.dynamics.advance`)."""

    SMOOTHED = "smoothed"          #: ``e + K·v_E`` averaged over a triangular window
    LINEAR_ADVANCE = "linear"      #: Marlin LA 1.5: speed offset ``K·a_E`` while accelerating
    WITHIN_MOVE = "within-move"    #: RRF: ``K·dv_E/dt`` within a move, no step between moves


class PaSyntax(StrEnum):
    """The command a firmware sets its advance factor ``K`` (s) with."""

    SET_PRESSURE_ADVANCE = "SET_PRESSURE_ADVANCE"  #: Klipper: ``ADVANCE=<K> [SMOOTH_TIME=<t>]``
    M900 = "M900"        #: Marlin LIN_ADVANCE: ``M900 K<K>`` (``T<tool>``), 0-10
    M572_D = "M572 D"    #: RepRapFirmware: ``M572 D<extruder> S<K>``
    M572_W = "M572 W"    #: Prusa Buddy: ``M572 S<K> [W<t>]``, no extruder

    @property
    def code(self) -> str:
        """The command word (``"M572"``)."""
        return self.value.split()[0]

    @property
    def template(self) -> str:
        """The command for tool 0 with ``{k}`` for the factor."""
        return _PA_TEMPLATES[self][0]

    @property
    def smooth_template(self) -> str | None:
        """What sets the smoothing window (``{t}``), appended; ``None``: no window."""
        return _PA_TEMPLATES[self][1]


_PA_TEMPLATES: dict[PaSyntax, tuple[str, str | None]] = {
    PaSyntax.SET_PRESSURE_ADVANCE: ("SET_PRESSURE_ADVANCE ADVANCE={k}", " SMOOTH_TIME={t}"),
    PaSyntax.M900: ("M900 K{k}", None),
    PaSyntax.M572_D: ("M572 D0 S{k}", None),
    PaSyntax.M572_W: ("M572 S{k}", " W{t}"),
}


class Firmware(StrEnum):
    """A firmware family (the ``firmware`` of a printer profile)."""

    KLIPPER = "klipper"
    MARLIN = "marlin"
    REPRAPFIRMWARE = "reprapfirmware"
    PRUSA = "prusa"
    REPETIER = "repetier"

    @classmethod
    def parse(cls, name: str | Firmware) -> Firmware:
        """The firmware called ``name`` (case and spaces ignored; ``rrf`` accepted).

        Raises
        ------
        ProfileError
            An unknown name (the message lists the allowed ones).
        """
        if isinstance(name, Firmware):
            return name
        key = str(name).strip().lower()
        key = _ALIASES.get(key, key)
        for fw in cls:
            if fw.value == key:
                return fw
        raise ProfileError("unknown firmware", field="firmware", value=name,
                           allowed=", ".join(f.value for f in cls) + " (rrf for "
                                   "reprapfirmware)")

    @property
    def label(self) -> str:
        """Human-readable name (``"RepRapFirmware"``)."""
        return _TRAITS[self].label

    @property
    def planner(self) -> PlannerFamily:
        """The planner family that plans this firmware's moves."""
        return _TRAITS[self].planner

    @property
    def advance(self) -> AdvanceAlgorithm:
        """The pressure-advance algorithm this firmware applies."""
        return _TRAITS[self].advance

    @property
    def pa_syntax(self) -> PaSyntax:
        """The command that sets the advance factor."""
        return _TRAITS[self].pa_syntax

    @property
    def smooths_advance(self) -> bool:
        """True where the advance command takes a smoothing window (Klipper, Prusa)."""
        return self.pa_syntax.smooth_template is not None

    @property
    def accel_template(self) -> str:
        """The command that sets the printing and travel acceleration (``{a}``, mm/s²).

        Klipper rejects ``M204`` with only ``P`` or only ``T`` and takes the minimum of
        both, so it is set with ``SET_VELOCITY_LIMIT``; the others read ``M204 P``
        (printing) and ``T`` (travel).
        """
        return ("SET_VELOCITY_LIMIT ACCEL={a}" if self.planner is PlannerFamily.KLIPPER
                else "M204 P{a} T{a}")

    @property
    def factor_decimals(self) -> int | None:
        """Decimals of ``M220``/``M221 S`` the firmware keeps (0: an integer percent);
        ``None`` where flowtwin does not model its multiplier commands."""
        return _TRAITS[self].factor_decimals

    @property
    def default_printer(self) -> str:
        """Built-in printer profile that checks a pattern when none is named."""
        return "generic-klipper" if self.planner is PlannerFamily.KLIPPER else "generic-marlin"


@dataclass(frozen=True, slots=True)
class _Traits:
    label: str
    planner: PlannerFamily
    advance: AdvanceAlgorithm
    pa_syntax: PaSyntax
    factor_decimals: int | None


#: Everything that differs between the firmwares, one row each.
_TRAITS: dict[Firmware, _Traits] = {
    # Klipper: S is a float (gcode_move.py); flowtwin sends three decimals
    Firmware.KLIPPER: _Traits("Klipper", PlannerFamily.KLIPPER, AdvanceAlgorithm.SMOOTHED,
                              PaSyntax.SET_PRESSURE_ADVANCE, 3),
    # Marlin: parser.value_int() - M221 S95.7 sets 95 %
    Firmware.MARLIN: _Traits("Marlin", PlannerFamily.MARLIN, AdvanceAlgorithm.LINEAR_ADVANCE,
                             PaSyntax.M900, 0),
    Firmware.REPRAPFIRMWARE: _Traits("RepRapFirmware", PlannerFamily.MARLIN,
                                     AdvanceAlgorithm.WITHIN_MOVE, PaSyntax.M572_D, None),
    Firmware.PRUSA: _Traits("Prusa (Buddy)", PlannerFamily.MARLIN, AdvanceAlgorithm.SMOOTHED,
                            PaSyntax.M572_W, None),
    Firmware.REPETIER: _Traits("Repetier-Firmware", PlannerFamily.MARLIN,
                               AdvanceAlgorithm.LINEAR_ADVANCE, PaSyntax.M900, None),
}

_ALIASES = {"rrf": "reprapfirmware"}
