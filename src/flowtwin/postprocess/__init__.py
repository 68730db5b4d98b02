"""The slicer's post-processing step: firmware-exact times, the twin's verdict, compensation.

:func:`postprocess` edits a G-code in place the way PrusaSlicer, SuperSlicer, OrcaSlicer and
Bambu Studio expect of a post-processing script: the slicer's time figures become the
planner's, a verdict goes to stderr and a JSON sidecar, and ``fail_on`` stops the export
when the twin predicts grinding or flow beyond the melt capacity. See
``docs/postprocess.md``.
"""

from flowtwin.postprocess.run import (
    FAIL_ON,
    PostprocessOptions,
    PostprocessResult,
    postprocess,
    sidecar_path,
)
from flowtwin.postprocess.slicer import SlicerContext, SlicerSettings

__all__ = ["FAIL_ON", "PostprocessOptions", "PostprocessResult", "SlicerContext",
           "SlicerSettings", "postprocess", "sidecar_path"]
