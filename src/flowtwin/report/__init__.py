"""Reports of simulations and compensations: the verdict, a toolpath viewer, plots, tables.

* :func:`build_verdict` — what a simulation says, in plain words and units
  (:class:`Verdict`), shared by the HTML report and ``flowtwin simulate``;
* :func:`write_report` / :func:`report_html` — the self-contained HTML report of a
  simulation; :func:`write_comparison` / :func:`comparison_html` — before and after
  ``compensate``;
* in Jupyter, a :class:`~flowtwin.simulation.SimulationResult` and a
  :class:`~flowtwin.compensation.CompensationReport` display their report themselves.

See ``docs/report.md``.
"""

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

if TYPE_CHECKING:
    from flowtwin.report.html import (
        comparison_html,
        report_html,
        source_text,
        write_comparison,
        write_report,
    )
    from flowtwin.report.spots import result_windowed
    from flowtwin.report.verdict import Verdict, build_verdict

__all__ = ["Verdict", "build_verdict", "comparison_html", "report_html", "result_windowed",
           "source_text", "write_comparison", "write_report"]

# the verdict alone (``flowtwin simulate``) does not load the HTML report's payload and plots
__getattr__, __dir__ = lazy_exports(__name__, {
    "comparison_html": "flowtwin.report.html", "report_html": "flowtwin.report.html",
    "source_text": "flowtwin.report.html", "write_comparison": "flowtwin.report.html",
    "write_report": "flowtwin.report.html", "result_windowed": "flowtwin.report.spots",
    "Verdict": "flowtwin.report.verdict", "build_verdict": "flowtwin.report.verdict",
})
