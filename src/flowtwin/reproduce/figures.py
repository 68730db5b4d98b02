"""Figure specifications of the reproduction (name, caption, drawing function)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from matplotlib.figure import Figure

from flowtwin.reproduce.claims import Claim

if TYPE_CHECKING:
    from flowtwin.reproduce.context import ReproContext

__all__ = ["FigureSpec", "PaperSection"]


@dataclass(frozen=True)
class FigureSpec:
    """A figure of the reproduction.

    Attributes
    ----------
    name
        File stem (``figures/<name>.png``) and the key claims refer to.
    caption
        What it shows, with the paper figure it mirrors.
    draw
        Draws it from the context (matplotlib ``Figure`` with an Agg canvas).
    """

    name: str
    caption: str
    draw: Callable[[ReproContext], Figure]


@dataclass(frozen=True)
class PaperSection:
    """Everything the reproduction knows about one paper.

    Attributes
    ----------
    key
        Paper key (command argument).
    title
        Citation.
    seed_id
        Seed number (``000`` … ``004``).
    claims
        Its claims (:class:`~flowtwin.reproduce.claims.Claim`).
    figures
        Its figures.
    notes
        Computes Markdown paragraphs for the report (findings that are not pass/fail rows).
    """

    key: str
    title: str
    seed_id: str
    claims: tuple[Claim, ...]
    figures: tuple[FigureSpec, ...]
    notes: Callable[[ReproContext], list[str]]
