"""What the slicer tells a post-processing script: its settings and where the file goes.

PrusaSlicer, SuperSlicer, OrcaSlicer and Bambu Studio run each post-processing script as
``$SHELL -c "<script> '<G-code path>'"`` (the path is the last argument) after putting
every configuration option into the environment as ``SLIC3R_<OPTION NAME IN CAPITALS>``
(``ConfigBase::setenv_`` in their ``libslic3r/Config.cpp``), plus ``SLIC3R_PP_HOST``
(``File``, or the print host's name when uploading) and ``SLIC3R_PP_OUTPUT_NAME`` (the final
path for ``File``, the name on the host otherwise). The G-code path may be a temporary copy
(``….gcode.pp`` in the system's temporary folder): the final name is the output name. See
``docs/postprocess.md`` for each slicer's behaviour.

Option names differ between the families (PrusaSlicer's ``temperature``,
``machine_max_feedrate_x`` against OrcaSlicer's ``nozzle_temperature``,
``machine_max_speed_x``); :class:`SlicerSettings` reads either. Settings come from the
environment when the slicer set them, else from the configuration block the slicer
embedded in the G-code, else there are none (the printer profile alone decides).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["ENV_PREFIX", "SlicerContext", "SlicerSettings", "first_float"]

#: Prefix of the environment variables the Slic3r family sets.
ENV_PREFIX = "SLIC3R_"
#: Variables about the post-processing run itself, not configuration options.
_RUN_VARIABLES = frozenset({"pp_host", "pp_output_name"})
#: Options whose presence says the configuration describes a printer (not just a host).
_PRINTER_KEYS = ("gcode_flavor", "nozzle_diameter", "machine_max_acceleration_x",
                 "machine_max_feedrate_x", "machine_max_speed_x", "printer_model")


def _first(raw: str | None) -> str | None:
    """First element of a slicer list value (``"0.4,0.4"`` → ``"0.4"``; per extruder or
    normal/stealth), stripped of quotes; ``None`` when empty."""
    if raw is None:
        return None
    text = str(raw).split(",")[0].split(";")[0].strip().strip('"').strip()
    return text or None


def first_float(raw: str | None) -> float | None:
    """The first element of a slicer list value as a number (``None``: unset, a
    percentage or not a number)."""
    text = _first(raw)
    if text is None or text.endswith("%"):
        return None
    try:
        value = float(text)
    except ValueError:
        return None
    return value if value == value else None


@dataclass(frozen=True, slots=True)
class SlicerSettings:
    """Configuration options of the slicer that produced the file.

    Attributes
    ----------
    options
        Option name (lower case, as in the slicer's configuration) → raw value.
    source
        ``"environment"`` (the slicer's ``SLIC3R_*`` variables) or ``"embedded"`` (the
        configuration block in the G-code).
    """

    options: Mapping[str, str]
    source: str

    def get(self, *names: str) -> str | None:
        """The raw value of the first of ``names`` that is set."""
        for name in names:
            value = self.options.get(name)
            if value is not None and str(value).strip() != "":
                return str(value)
        return None

    @property
    def flavor(self) -> str | None:
        """``gcode_flavor`` (``marlin2``, ``klipper``, ``reprapfirmware``, …)."""
        v = _first(self.get("gcode_flavor"))
        return v.lower() if v else None

    @property
    def printer_model(self) -> str | None:
        """``printer_model`` (``MK4S``, ``Creality K1 Max``, …)."""
        return _first(self.get("printer_model"))

    @property
    def nozzle_diameter_mm(self) -> float | None:
        """Nozzle diameter of the first extruder, mm."""
        return first_float(self.get("nozzle_diameter"))

    @property
    def filament_diameter_mm(self) -> float | None:
        """Filament diameter of the first extruder, mm."""
        return first_float(self.get("filament_diameter"))

    @property
    def temperature_c(self) -> float | None:
        """Nozzle temperature after the first layer, °C (PrusaSlicer ``temperature``,
        OrcaSlicer / Bambu ``nozzle_temperature``); ``None`` when unset or 0."""
        t = first_float(self.get("temperature", "nozzle_temperature"))
        return t if t is not None and t > 0 else None

    @property
    def pressure_advance_s(self) -> float | None:
        """The advance factor the slicer writes into the G-code (OrcaSlicer / Bambu
        ``pressure_advance`` with ``enable_pressure_advance``), s; ``None`` when the slicer
        leaves the firmware's own setting in force (PrusaSlicer has no such option)."""
        enabled = _first(self.get("enable_pressure_advance"))
        if enabled is None or enabled.lower() not in ("1", "true"):
            return None
        return first_float(self.get("pressure_advance"))

    def describes_printer(self) -> bool:
        """True when the options describe a printer (flavor, nozzle, machine limits)."""
        return any(self.get(k) is not None for k in _PRINTER_KEYS)

    def mode(self, index: int) -> dict[str, str]:
        """The options with every ``machine_*`` list reduced to its element ``index``
        (0 = normal mode, 1 = PrusaSlicer's silent / stealth mode), for the machine-limit
        reader (which takes the first element)."""
        out = dict(self.options)
        for key, raw in self.options.items():
            if key.startswith("machine_") and "," in str(raw):
                parts = [p.strip() for p in str(raw).split(",")]
                out[key] = parts[min(index, len(parts) - 1)]
        return out

    def has_silent_mode(self) -> bool:
        """True when the machine limits carry a second (silent / stealth) value set."""
        return any(k.startswith("machine_max_") and "," in str(v)
                   for k, v in self.options.items())


@dataclass(frozen=True, slots=True)
class SlicerContext:
    """What the slicer passed to this run.

    Attributes
    ----------
    environment
        The ``SLIC3R_*`` options (lower-case names without the prefix; the run variables
        ``pp_host`` and ``pp_output_name`` excluded).
    host
        ``SLIC3R_PP_HOST``: ``"File"`` for an export to a file, else the print host's name
        (``"OctoPrint"``, ``"PrusaLink"``, …); ``None`` outside a slicer.
    output_name
        ``SLIC3R_PP_OUTPUT_NAME``: the final path (``File``) or the name on the host.
    """

    environment: Mapping[str, str] = field(default_factory=dict)
    host: str | None = None
    output_name: str | None = None

    @classmethod
    def from_environment(cls, env: Mapping[str, str] | None = None) -> SlicerContext:
        """Read the ``SLIC3R_*`` variables of ``env`` (default: ``os.environ``)."""
        env = os.environ if env is None else env
        options: dict[str, str] = {}
        for key, value in env.items():
            if key.startswith(ENV_PREFIX) and len(key) > len(ENV_PREFIX):
                name = key[len(ENV_PREFIX):].lower()
                if name not in _RUN_VARIABLES:
                    options[name] = value
        host = env.get(ENV_PREFIX + "PP_HOST") or None
        output = env.get(ENV_PREFIX + "PP_OUTPUT_NAME") or None
        return cls(environment=options, host=host, output_name=output)

    @property
    def in_slicer(self) -> bool:
        """True when a slicer started this run (it set its ``SLIC3R_*`` variables)."""
        return bool(self.environment) or self.host is not None

    def settings(self, embedded: Mapping[str, object] | None) -> SlicerSettings | None:
        """The slicer's options: the environment's when they describe a printer, else the
        configuration block embedded in the G-code (``MoveTable.metadata["slicer_config"]``),
        else ``None``."""
        env = SlicerSettings(dict(self.environment), "environment")
        if env.describes_printer():
            return env
        if embedded:
            emb = SlicerSettings({str(k): str(v) for k, v in embedded.items()}, "embedded")
            if emb.describes_printer():
                return emb
        return None

    def final_path(self, gcode: Path) -> Path:
        """Where the G-code ends up: the output name when the slicer exports to a file
        (the script may be working on a temporary copy), else ``gcode`` itself."""
        name = self.output_name
        if name and (self.host is None or self.host == "File"):
            out = Path(name)
            if out.is_absolute() and out.parent.is_dir():
                return out
        return gcode
