"""A synthetic slip camera: real images rendered from a known motion (ground truth)."""

from flowtwin.vision.synth.motion import MotionSeries, integrate_piecewise_linear
from flowtwin.vision.synth.render import SyntheticCamera, SyntheticFrame, render_from_series
from flowtwin.vision.synth.scene import SceneSpec
from flowtwin.vision.synth.write import (
    timestamps_text,
    write_config_toml,
    write_image_folder,
    write_video,
)

__all__ = ["MotionSeries", "SceneSpec", "SyntheticCamera", "SyntheticFrame",
           "integrate_piecewise_linear", "render_from_series", "timestamps_text",
           "write_config_toml", "write_image_folder", "write_video"]
