"""The pattern library: every calibration pattern by name, with its parameter type.

=========  ==============================================  ===============
kind       what it tests                                   module
=========  ==============================================  ===============
kline      advance factor: slow/fast/slow lines [001]      :mod:`.kline`
chevron    advance factor: Ellis-style nested corners      :mod:`.chevron`
tower      advance factor: ``K = start + step·z``          :mod:`.tower`
flow       extrusion multiplier: solid blocks              :mod:`.flow_rate`
maxflow    maximum volumetric speed: rising-flow lines     :mod:`.flow_rate`
flowline   lag: one line alternating ``v/4`` and ``v``     :mod:`.flow_rate`
=========  ==============================================  ===============
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

from flowtwin.calibration.patterns.chevron import ChevronParams, chevron_pattern
from flowtwin.calibration.patterns.flow_rate import (
    FlowBlockParams,
    FlowLineParams,
    MaxFlowParams,
    flow_block_pattern,
    flowline_pattern,
    maxflow_pattern,
)
from flowtwin.calibration.patterns.kline import KLineParams, kline_pattern
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.calibration.patterns.tower import TowerParams, tower_pattern
from flowtwin.errors import CalibrationError

__all__ = ["PATTERN_KINDS", "PatternKind", "generate_pattern", "pattern_params"]


@dataclasses.dataclass(frozen=True, slots=True)
class PatternKind:
    """One entry of the library: parameter type, generator and a one-line description."""

    name: str
    params_type: type[Any]
    generate: Callable[[PrintSettings, Any], Pattern]
    description: str


#: Every pattern by name.
PATTERN_KINDS: Mapping[str, PatternKind] = {
    k.name: k for k in (
        PatternKind("kline", KLineParams, kline_pattern,
                    "Marlin-style K-factor lines: 20/40/20 mm slow/fast/slow, one K per line"),
        PatternKind("chevron", ChevronParams, chevron_pattern,
                    "Ellis-style nested 90° chevrons, one K per whole chevron"),
        PatternKind("tower", TowerParams, tower_pattern,
                    "square tower with K = k_start + k_step_per_mm·z"),
        PatternKind("flow", FlowBlockParams, flow_block_pattern,
                    "extrusion-multiplier blocks"),
        PatternKind("maxflow", MaxFlowParams, maxflow_pattern,
                    "lines of rising volumetric flow (maximum volumetric speed)"),
        PatternKind("flowline", FlowLineParams, flowline_pattern,
                    "a line alternating v/4 and v for a target flow (lag for sensors/cameras)"),
    )
}


def pattern_params(kind: str, values: Mapping[str, Any] | None = None) -> Any:
    """The parameter object of pattern ``kind`` with ``values`` replacing defaults.

    Raises
    ------
    CalibrationError
        Unknown kind, or a parameter the kind does not have (the message lists the ones
        it has), or an invalid value.
    """
    entry = _entry(kind)
    values = dict(values or {})
    fields = {f.name for f in dataclasses.fields(entry.params_type)}
    for key in values:
        if key not in fields:
            raise CalibrationError(f"the {kind} pattern has no parameter {key!r}", field=key,
                                   allowed=", ".join(sorted(fields)))
    return entry.params_type(**values)


def generate_pattern(kind: str, settings: PrintSettings | None = None,
                     params: Mapping[str, Any] | Any | None = None) -> Pattern:
    """Generate the pattern ``kind``.

    Parameters
    ----------
    kind
        A key of :data:`PATTERN_KINDS`.
    settings
        Shared print settings; defaults to :class:`PrintSettings` (Klipper).
    params
        The kind's parameter object, or a mapping of parameter names to values.

    Returns
    -------
    Pattern
    """
    entry = _entry(kind)
    if params is None or isinstance(params, Mapping):
        params = pattern_params(kind, params)
    elif not isinstance(params, entry.params_type):
        raise CalibrationError(f"parameters of the {kind} pattern must be a "
                               f"{entry.params_type.__name__}", field="params",
                               value=type(params).__name__)
    return entry.generate(settings or PrintSettings(), params)


def _entry(kind: str) -> PatternKind:
    entry = PATTERN_KINDS.get(kind)
    if entry is None:
        raise CalibrationError("unknown pattern", field="kind", value=kind,
                               allowed=", ".join(PATTERN_KINDS))
    return entry
