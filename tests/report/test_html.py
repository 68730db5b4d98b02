"""The HTML report: self-contained, escaped, with the promised sections."""

from __future__ import annotations

import re
from pathlib import Path

from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.report import write_report
from flowtwin.simulation import simulate


def test_report_is_self_contained_and_escapes_gcode_text(tmp_path: Path) -> None:
    gcode = tmp_path / "x.gcode"
    write_print(gcode, PrintSpec(layers=3))
    text = gcode.read_text().replace(";TYPE:Perimeter", ";TYPE:<script>alert(1)</script>")
    evil = tmp_path / "&<b>evil.gcode"
    evil.write_text(text)
    out = write_report(simulate(evil, series_dt_s=0.02), tmp_path / "r" / "report.html")
    doc = out.read_text()
    # no resource from the network: plotly.js is inlined, no tag loads anything external
    assert not re.search(r"""<(script|link|img|iframe)[^>]*(src|href)=["']?(https?:)?//""",
                         doc)
    assert len(doc) > 3_000_000  # the plotly.js bundle itself is in the file
    assert "<script>alert(1)</script>" not in doc
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in doc
    assert "<b>evil" not in doc and "&amp;&lt;b&gt;evil" in doc
    for section in ("Volume flow along the print", "Bead width per extruding move",
                    "Toolpath coloured by predicted", "Drive slip and feed-force margin",
                    "Per layer", "Per feature", "Worst moves by width error"):
        assert section in doc, section
    assert doc.count("Plotly.newPlot") == 4
    assert [p.name for p in out.parent.iterdir()] == ["report.html"]  # written atomically
