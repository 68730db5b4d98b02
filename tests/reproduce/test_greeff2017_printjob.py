"""The print-job part of the greeff2017 reproduction: per-temperature figures and the figure.

The full comparison is the claims' (tests/reproduce/test_claims.py); here a one-layer-per-
set print exercises the helpers and the drawing on the same code path.
"""

from __future__ import annotations

import io

import cv2
import pytest

from flowtwin.reproduce.greeff2017_loop import (
    PrintJobComparison,
    PrintJobSettings,
    compare_print_jobs,
)
from flowtwin.reproduce.greeff2017_polygon import PolygonSpec
from flowtwin.reproduce.greeff2017_printjob import (
    PRINT_JOB_FIGURE,
    print_job_figure,
    set_slip,
    set_speed_pct,
)


@pytest.fixture(scope="module")
def small() -> PrintJobComparison:
    cv2.setNumThreads(1)
    return compare_print_jobs(PrintJobSettings(part=PolygonSpec.greeff(layers_per_set=1),
                                               seed=4))


def test_per_temperature_slip_and_speed(small: PrintJobComparison) -> None:
    # 190 °C: the loop slows the drive and the slip falls; 230 °C: little slip either way
    assert set_slip(small.on, 190.0) < set_slip(small.off, 190.0)
    assert set_slip(small.off, 190.0) > 0.3 > 0.15 > set_slip(small.off, 230.0)
    assert set_speed_pct(small.off, 190.0) == pytest.approx(100.0, rel=1e-12)
    assert 50.0 <= set_speed_pct(small.on, 190.0) < 100.0


def test_figure_draws(small: PrintJobComparison) -> None:
    fig = print_job_figure(small)
    assert len(fig.axes) == 4                    # two panels, each with a second y axis
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=60)
    assert buf.getvalue()[:8] == b"\x89PNG\r\n\x1a\n"
    assert PRINT_JOB_FIGURE.name == "print-job" and "[003 Figs. 11" in PRINT_JOB_FIGURE.caption
