"""Prusa binary G-code (``.bgcode``): read, write, MeatPack (see ``docs/gcode.md``)."""

from flowtwin.gcode.bgcode.format import (
    BlockType,
    ChecksumType,
    Compression,
    GcodeEncoding,
    Thumbnail,
    ThumbnailFormat,
)
from flowtwin.gcode.bgcode.read import BgcodeInfo, BgcodeText, iter_blocks, read_bgcode_info
from flowtwin.gcode.bgcode.write import BgcodeOptions, text_to_bgcode, write_bgcode

__all__ = ["BgcodeInfo", "BgcodeOptions", "BgcodeText", "BlockType", "ChecksumType",
           "Compression", "GcodeEncoding", "Thumbnail", "ThumbnailFormat", "iter_blocks",
           "read_bgcode_info", "text_to_bgcode", "write_bgcode"]
