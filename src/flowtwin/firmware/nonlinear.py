"""Nonlinear extrusion: which firmware scales E by a function of the extrusion speed, how,
and the command that sets it (``M592``).

==================  ==============================================  ==========================
firmware            E multiplier at requested E speed ``v`` (mm/s)  command
==================  ==============================================  ==========================
``marlin``          ``C + max(A·v² + B·v, 0)``, ``v`` instantaneous  ``M592 S1 A<a> B<b> C<c>``
``reprapfirmware``  ``1 + min(A·v + B·v², L)``, ``v`` move average   ``M592 D0 A<a> B<b> L<l>``
``klipper``         none                                            —
``prusa``           none                                            —
``repetier``        none                                            —
==================  ==============================================  ==========================

Marlin: ``NONLINEAR_EXTRUSION`` (``Stepper::calc_nonlinear_e``, bugfix-2.1.x, where ``A``
is quadratic and ``B`` linear and ``S`` enables it; the feature's first version, 2023, had
``A`` linear, ``B`` quadratic and no ``S``), applied to every step of a forward extrusion
that moves an axis. RepRapFirmware: ``M592`` (``DDA::Prepare``), applied to printing moves,
``L`` defaults to 0.2. Both leave E-only moves (retractions, loading) alone.
"""

from __future__ import annotations

from enum import StrEnum

from flowtwin.firmware.kinds import Firmware

__all__ = ["RRF_DEFAULT_LIMIT", "NonlinearFormula", "nonlinear_command", "nonlinear_formula"]

#: RepRapFirmware's default upper limit of the correction (``DefaultNonlinearExtrusionLimit``).
RRF_DEFAULT_LIMIT = 0.2


class NonlinearFormula(StrEnum):
    """How a firmware scales E with the extrusion speed."""

    NONE = "none"                   #: no nonlinear extrusion
    INSTANTANEOUS = "instantaneous"  #: Marlin: ``C + max(A·v² + B·v, 0)`` per step
    MOVE_AVERAGE = "move-average"    #: RRF: ``1 + min(A·v + B·v², L)`` per move

_FORMULA = {Firmware.MARLIN: NonlinearFormula.INSTANTANEOUS,
            Firmware.REPRAPFIRMWARE: NonlinearFormula.MOVE_AVERAGE}


def nonlinear_formula(firmware: Firmware) -> NonlinearFormula:
    """The nonlinear-extrusion formula ``firmware`` applies (see the module table)."""
    return _FORMULA.get(firmware, NonlinearFormula.NONE)


def nonlinear_command(firmware: Firmware, a: float, b: float, *, c: float = 1.0,
                      limit: float = RRF_DEFAULT_LIMIT) -> str | None:
    """The ``M592`` that sets the coefficients, six significant digits; ``None`` for a
    firmware without nonlinear extrusion.

    Parameters
    ----------
    firmware
        The firmware.
    a, b
        Its ``A`` and ``B`` (Marlin: quadratic and linear; RRF: linear and quadratic).
    c
        Marlin's constant ``C``.
    limit
        RRF's ``L``.
    """
    formula = nonlinear_formula(firmware)
    if formula is NonlinearFormula.INSTANTANEOUS:
        return f"M592 S1 A{a:.6g} B{b:.6g} C{c:.6g}"
    if formula is NonlinearFormula.MOVE_AVERAGE:
        return f"M592 D0 A{a:.6g} B{b:.6g} L{limit:.6g}"
    return None
