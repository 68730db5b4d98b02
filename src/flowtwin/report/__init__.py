"""Reports of simulations: self-contained HTML with plots and tables."""

from flowtwin.report.html import write_report

__all__ = ["write_report"]
