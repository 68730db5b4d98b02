"""Claims of the seed papers, the rows that check them, and the registry.

A :class:`Claim` is one quantitative statement of a paper with a small function that
computes flowtwin's value from the library; running it gives a :class:`Row` — claim,
paper value, flowtwin value, tolerance, pass — that ``flowtwin reproduce`` prints and
``docs/reproduction.md`` shows. Every row is computed when it is run, never pasted.

Three kinds of row (:class:`RowKind`):

``reproduced``
    flowtwin computes what the paper states from inputs that were not fitted to it; pass =
    within a tolerance that follows the paper's printed precision or a stated physical
    argument.
``anchor``
    the value is an input of flowtwin's defaults: a default fitted to it (Table II's lag
    factor, the slip at 215 °C) or the published number a model was built on (the test
    stand's laws, recovered by its fits). The row shows the model carries it; it is not
    evidence that flowtwin predicts it.
``data check``
    the paper's own numbers disagree with each other (e.g. Table 3's ``F_p,min`` of roller
    #3 against Eq. 9); the row computes the disagreement and its explanation, and passes
    when the disagreement is exactly the documented one — so a changed data file or a
    changed function cannot hide it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from flowtwin.reproduce.context import ReproContext

__all__ = [
    "Claim",
    "Outcome",
    "Row",
    "RowKind",
    "rounded",
    "within_abs",
    "within_rel",
]



class RowKind(StrEnum):
    """What a row is evidence of (see the module docstring)."""

    REPRODUCED = "reproduced"
    ANCHOR = "anchor"
    DATA_CHECK = "data check"


Value = float | int | str | bool | list[Any] | None


@dataclass(frozen=True)
class Outcome:
    """What a claim's function returns.

    Attributes
    ----------
    paper_value
        The paper's number (or list, or short text for a qualitative statement).
    flowtwin_value
        flowtwin's computed number (or list, or text).
    tolerance
        The pass criterion in words, with its number.
    passed
        Whether flowtwin's value meets the criterion.
    note
        How the value was computed and anything a reader must know.
    """

    paper_value: Value
    flowtwin_value: Value
    tolerance: str
    passed: bool
    note: str = ""


@dataclass(frozen=True)
class Claim:
    """One quantitative claim of a paper.

    Attributes
    ----------
    paper
        Paper key (``nienhaus2021``, ``tronvoll2019``, ``theory``, ``greeff2017``,
        ``jin2009``).
    claim_id
        Unique id within the paper (used as the test id).
    text
        The claim in words.
    source
        Where the paper states it (``[000 Table 3]``).
    compute
        Computes the outcome from a :class:`~flowtwin.reproduce.context.ReproContext`.
    unit
        Unit of the values (empty for dimensionless or text).
    figure
        Name of the figure that shows it (``None``: none).
    kind
        What the row is evidence of: reproduced, anchor or data check.
    engine
        Which part of flowtwin computes the value.
    """

    paper: str
    claim_id: str
    text: str
    source: str
    compute: Callable[[ReproContext], Outcome]
    unit: str = ""
    figure: str | None = None
    kind: RowKind = RowKind.REPRODUCED
    engine: str = ""

    @property
    def key(self) -> str:
        """``paper/claim_id``."""
        return f"{self.paper}/{self.claim_id}"

    def run(self, ctx: ReproContext) -> Row:
        """Compute the claim and return its row."""
        out = self.compute(ctx)
        return Row(paper=self.paper, claim_id=self.claim_id, claim=self.text,
                   source=self.source, paper_value=out.paper_value,
                   flowtwin_value=out.flowtwin_value, tolerance=out.tolerance,
                   passed=bool(out.passed), unit=self.unit, kind=self.kind,
                   figure=self.figure, engine=self.engine, note=out.note)


@dataclass(frozen=True)
class Row:
    """A computed claim: what ``--json`` prints and ``docs/reproduction.md`` tabulates."""

    paper: str
    claim_id: str
    claim: str
    source: str
    paper_value: Value
    flowtwin_value: Value
    tolerance: str
    passed: bool
    unit: str = ""
    kind: RowKind = RowKind.REPRODUCED
    figure: str | None = None
    engine: str = ""
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict; ``pass`` is the pass flag."""
        return {"paper": self.paper, "id": self.claim_id, "claim": self.claim,
                "source": self.source, "paper_value": _jsonable(self.paper_value),
                "flowtwin_value": _jsonable(self.flowtwin_value), "unit": self.unit,
                "tolerance": self.tolerance, "pass": self.passed, "kind": str(self.kind),
                "figure": self.figure, "engine": self.engine, "note": self.note}


def _jsonable(value: Value) -> Value:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    return value


def within_rel(paper: float, value: float, rel: float, *, why: str, note: str = "",
               digits: int = 4) -> Outcome:
    """Outcome for ``|value − paper| ≤ rel·|paper|``.

    Parameters
    ----------
    paper, value
        The paper's and flowtwin's numbers.
    rel
        Relative tolerance (fraction).
    why
        Justification of the tolerance (shown with it).
    note
        Extra note.
    digits
        Significant digits of the reported flowtwin value.
    """
    ok = math.isfinite(value) and abs(value - paper) <= rel * abs(paper)
    dev = (value - paper) / paper if paper != 0 and math.isfinite(value) else math.nan
    return Outcome(paper, _round(value, digits), f"±{100 * rel:g} % ({why})", ok,
                   _join(note, f"deviation {100 * dev:+.2f} %"))


def within_abs(paper: float, value: float, tol: float, *, unit: str, why: str,
               note: str = "", digits: int = 4) -> Outcome:
    """Outcome for ``|value − paper| ≤ tol``.

    Parameters
    ----------
    paper, value
        The paper's and flowtwin's numbers.
    tol
        Absolute tolerance, in ``unit``.
    unit
        Unit of the tolerance (shown).
    why
        Justification of the tolerance.
    note
        Extra note.
    digits
        Significant digits of the reported flowtwin value.
    """
    ok = math.isfinite(value) and abs(value - paper) <= tol
    return Outcome(paper, _round(value, digits), f"±{tol:g} {unit} ({why})".replace("  ", " "),
                   ok, _join(note, f"deviation {value - paper:+.4g} {unit}".rstrip()))


def _round(value: float, digits: int) -> float:
    if not math.isfinite(value) or value == 0.0:
        return value
    return float(f"{value:.{digits}g}")


def _join(*parts: str) -> str:
    return "; ".join(p for p in parts if p)


def rounded(values: Sequence[float], digits: int = 4) -> list[Any]:
    """Round a sequence of floats to ``digits`` significant digits (for rows)."""
    return [_round(float(v), digits) for v in values]
