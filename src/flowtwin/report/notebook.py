"""Rich display in Jupyter: a simulation or a compensation shows its report in the cell.

The report page goes into an ``<iframe srcdoc=…>`` with ``sandbox="allow-scripts"``: its
scripts run in their own document with an opaque origin, so they neither see the notebook
nor are disturbed by its styles and scripts, and the page needs no server or file.
"""

from __future__ import annotations

import html
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from flowtwin.compensation.pipeline import CompensationReport
    from flowtwin.simulation import SimulationResult

__all__ = ["compensation_repr", "iframe", "simulation_repr"]

#: Height of the report frame in a notebook cell, CSS pixels.
FRAME_HEIGHT_PX = 900


def iframe(page: str, *, height_px: int = FRAME_HEIGHT_PX) -> str:
    """``page`` (a whole HTML document) in a sandboxed ``<iframe srcdoc>``."""
    return (f'<iframe class="flowtwin-report" sandbox="allow-scripts" '
            f'style="width:100%;height:{int(height_px)}px;border:1px solid #ccc" '
            f'srcdoc="{html.escape(page, quote=True)}"></iframe>')


def simulation_repr(result: SimulationResult) -> str:
    """The report of ``result`` for ``_repr_html_``."""
    from flowtwin.report.html import report_html

    return iframe(report_html(result))


def compensation_repr(report: CompensationReport) -> str:
    """The before/after report of ``report`` for ``_repr_html_`` (its summary table when the
    report does not carry its simulations)."""
    from flowtwin.report.html import comparison_html

    if report.original_result is None or report.compensated_result is None or \
            report.piece_row is None:
        rows = "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v))}</td></tr>"
                       for k, v in report.as_dict().items() if not isinstance(v, list | dict))
        return f"<table>{rows}</table>"
    return iframe(comparison_html(report.original_result, report.compensated_result,
                                  report.piece_row, summary=report.as_dict(),
                                  warnings=report.warnings))
