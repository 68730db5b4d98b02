"""What a slicer's G-code flavor changes in the meaning of ``E``.

* :func:`volumetric_flavor`: CuraEngine writes ``;FLAVOR:UltiGCode`` (the Ultimaker 2's
  firmware) and ``;FLAVOR:Marlin(Volumetric)`` (its "RepRap (Volumetric)") as the first line
  of files whose every E is in mm³, with no ``M200``: the printer is set to volumetric mode
  beforehand (CuraEngine ``GCodeExport::setFlavor``: ``is_volumatric`` for exactly these
  two). The reader switches E to mm³ from the first line.
* :func:`check_extrusion_axis`: Slic3r's ``extrusion_axis`` setting, and PrusaSlicer's
  ``mach3`` and ``machinekit`` flavors (which write the extruder on ``A`` whatever
  ``extrusion_axis`` says: PrusaSlicer 2.5 embeds ``extrusion_axis = E`` in such a file),
  put the extruder's moves in words such as ``G1 … A1.234``; read for ``E`` they would be a
  print that extrudes nothing, so the file is refused.
"""

from __future__ import annotations

import re

from flowtwin.errors import GcodeError

__all__ = ["HEADER_BYTES", "check_extrusion_axis", "volumetric_flavor"]

#: How far into a file the flavor line is looked for, bytes.
HEADER_BYTES = 4096

_VOLUMETRIC_FLAVOR = re.compile(rb"^;FLAVOR:(UltiGCode|Marlin\(Volumetric\))[ \t]*\r?$",
                                re.MULTILINE)


def volumetric_flavor(head: bytes) -> str | None:
    """The volumetric flavor named in the first :data:`HEADER_BYTES` of a file, else None.

    Parameters
    ----------
    head
        The file's first bytes (more are ignored).
    """
    m = _VOLUMETRIC_FLAVOR.search(head, 0, HEADER_BYTES)
    return None if m is None else m.group(1).decode()


def check_extrusion_axis(metadata: dict[str, object], name: str) -> None:
    """Refuse a file whose slicer moved the extruder on another axis than ``E``.

    Parameters
    ----------
    metadata
        The file's metadata (its embedded ``slicer_config``, when there is one).
    name
        The file, for the message.

    Raises
    ------
    GcodeError
        Naming the setting (``extrusion_axis`` or ``gcode_flavor``) and its value.
    """
    config = metadata.get("slicer_config")
    if not isinstance(config, dict):
        return
    axis = str(config.get("extrusion_axis", "E")).strip()
    flavor = str(config.get("gcode_flavor", "")).strip()
    if axis in ("", "E") and flavor in ("mach3", "machinekit"):
        axis, field = "A", "gcode_flavor"
    else:
        field = "extrusion_axis"
    if axis not in ("", "E"):
        raise GcodeError(f"the slicer wrote the extruder's moves on axis {axis}, not E: "
                         "flowtwin reads extrusion from E words only", source=name,
                         field=field, value=flavor if field == "gcode_flavor" else axis,
                         allowed="an extruder on E (extrusion_axis = E; a flavor other than "
                         "mach3 or machinekit)")
