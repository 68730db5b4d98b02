"""Machine-vision measurement of filament speed, gear speed, slip and width [003].

A camera looks at the drive gear and the filament before and after it ([003 Fig. 2]);
features are tracked with Shi–Tomasi + pyramidal Lucas–Kanade, the width is measured
from the derivative extrema across the filament, and slip follows [000 Eq. 1]. See
docs/vision.md. The synthetic camera in :mod:`flowtwin.vision.synth` renders real frames
from a known motion so that accuracy is measured against ground truth.
"""

from flowtwin.vision.axis import AxisEstimate, estimate_gear_axis, fit_rotation_axis
from flowtwin.vision.capture import Frame, FrameSource, open_source, read_timestamps_file
from flowtwin.vision.config import TrackingParams, VisionConfig, build_config, load_config_file
from flowtwin.vision.flow import (
    gaussian_smooth,
    slip_fraction,
    speed_mm_s,
    surface_speed_mm_s,
    volume_flow_mm3_s,
)
from flowtwin.vision.inspect import InspectReport, annotate_frame, inspect_source
from flowtwin.vision.loader import load_grey, read_grey_image, to_grey_u8
from flowtwin.vision.measure import (
    Pipeline,
    SourceInfo,
    find_gear_axis,
    measure,
    measure_frames,
)
from flowtwin.vision.plot import plot_png, write_plot
from flowtwin.vision.readings import (
    Quality,
    VisionResult,
    VisionSeries,
    VisionSummary,
    write_csv,
    write_parquet,
)
from flowtwin.vision.roi import Roi, RoiSet, parse_roi, parse_rois
from flowtwin.vision.width import (
    EdgeMeasurement,
    calibration_factor,
    expected_width_px,
    measure_width_px,
)

__all__ = [
    "AxisEstimate", "EdgeMeasurement", "Frame", "FrameSource", "InspectReport", "Pipeline",
    "Quality", "Roi", "RoiSet", "SourceInfo", "TrackingParams", "VisionConfig", "VisionResult",
    "VisionSeries", "VisionSummary", "annotate_frame", "build_config", "calibration_factor",
    "estimate_gear_axis", "expected_width_px", "find_gear_axis", "fit_rotation_axis",
    "gaussian_smooth", "inspect_source", "load_config_file", "load_grey", "measure",
    "measure_frames", "measure_width_px", "open_source", "parse_roi", "parse_rois",
    "plot_png", "read_grey_image", "read_timestamps_file", "slip_fraction", "speed_mm_s",
    "surface_speed_mm_s", "to_grey_u8", "volume_flow_mm3_s", "write_csv", "write_parquet",
    "write_plot",
]
