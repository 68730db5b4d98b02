"""Sweep parameters: dotted paths into a machine's profiles and the values they take.

Path scheme
-----------
A parameter is addressed as ``PART.KEY[.KEY...]``, where ``PART`` is one of the profiles a
:class:`~flowtwin.profiles.Machine` is made of and the keys are the field names of that
profile's TOML table (docs/profiles.md), e.g.::

    setup.temperature_c                     nozzle temperature, °C (a set-up value)
    setup.material                          swap a part by library name or .toml path
    drive.pinch_force_n                     pinch force, N
    drive.roller_id                         roller 1–7 of [000]
    drive.slip_overrides.k_s_pct_N          one slip parameter of the roller
    printer.pressure_advance.k_s            pressure advance K, s
    printer.limits.max_accel_mm_s2          Klipper acceleration limit
    hotend.nozzle_diameter_mm               nozzle diameter, mm
    material.viscosity.b_per_c              a parameter of the viscosity law

``material.temperature_c`` (the spelling of the issue that asked for sweeps) is accepted as
an alias of ``setup.temperature_c``; no other alias exists. Several paths joined by ``+``
take the same value together (``hotend.nozzle_diameter_mm+printer.extruder.nozzle_diameter_mm``
changes the nozzle and the firmware's idea of it at once).

Values
------
``a:b:step``
    An inclusive range, computed in decimal so ``0.1:0.3:0.1`` is ``0.1, 0.2, 0.3`` exactly;
    ``b`` is included when it lies on the grid.
``a,b,c``
    A list (numbers, ``true``/``false``, or names for string keys).
``a:b``
    A continuous interval; only with random sampling (``--sample``).
"""

from __future__ import annotations

import enum
import math
import types
import typing
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from typing import Any, Literal

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo

from flowtwin.errors import ProfileError
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.filament import FilamentProfile
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.profiles.material import MaterialProfile
from flowtwin.profiles.printer import PrinterProfile
from flowtwin.profiles.setup import SetupProfile

__all__ = [
    "ALIASES",
    "PARTS",
    "Axis",
    "ParamValue",
    "ValueKind",
    "describe_path",
    "parse_axis",
    "resolve_path",
]

#: A value a parameter takes.
ParamValue = float | int | bool | str

#: Type of the value a path accepts.
ValueKind = Literal["float", "int", "bool", "str"]

#: The profiles of a machine that a path may start with, and their models.
PARTS: dict[str, type[BaseModel]] = {
    "setup": SetupProfile,
    "printer": PrinterProfile,
    "drive": DriveProfile,
    "hotend": HotendProfile,
    "material": MaterialProfile,
    "filament": FilamentProfile,
}

#: Documented alternative spellings (alias -> canonical path).
ALIASES: dict[str, str] = {"material.temperature_c": "setup.temperature_c"}

_HINTS: dict[str, str] = {
    "roller": "the roller is chosen by drive.roller_id and its slip parameters are changed "
              "with drive.slip_overrides.<key>",
    "temperature_c": "the print temperature is setup.temperature_c",
}

#: Grids larger than this must be sampled (``--sample``).
MAX_GRID_POINTS = 1_000_000


@dataclass(frozen=True, slots=True)
class PathInfo:
    """What a dotted parameter path points at.

    Attributes
    ----------
    path
        The canonical dotted path.
    part
        The profile it starts with (a key of :data:`PARTS`).
    keys
        The keys inside that profile.
    kind
        The type of value the key accepts.
    choices
        The allowed strings of a ``Literal`` key, else empty.
    allowed
        The declared range or choices in words (for error messages).
    """

    path: str
    part: str
    keys: tuple[str, ...]
    kind: ValueKind
    choices: tuple[str, ...]
    allowed: str


@dataclass(frozen=True, slots=True)
class Axis:
    """One swept parameter (or several linked paths) and its values.

    Attributes
    ----------
    paths
        Canonical paths that take the value together (usually one).
    kind
        Type of the values.
    values
        The discrete values, in order; empty for a continuous interval.
    interval
        ``(low, high)`` of a continuous interval (sampling only), else ``None``.
    text
        The ``--param`` text it came from (for messages).
    """

    paths: tuple[str, ...]
    kind: ValueKind
    values: tuple[ParamValue, ...]
    interval: tuple[float, float] | None
    text: str

    @property
    def name(self) -> str:
        """Column name of the axis: the paths joined by ``+``."""
        return "+".join(self.paths)

    @property
    def size(self) -> int | None:
        """Number of discrete values (``None`` for an interval)."""
        return None if self.interval is not None else len(self.values)


def _candidates(annotation: Any) -> list[Any]:
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _candidates(typing.get_args(annotation)[0])
    if origin is typing.Union or origin is types.UnionType:
        out: list[Any] = []
        for arg in typing.get_args(annotation):
            if arg is not type(None):
                out.extend(_candidates(arg))
        return out
    return [annotation]


def _is_model(tp: Any) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _bounds(field: FieldInfo) -> list[str]:
    out: list[str] = []
    for meta in field.metadata:
        for cls, op, attr in ((at.Gt, ">", "gt"), (at.Ge, ">=", "ge"), (at.Lt, "<", "lt"),
                              (at.Le, "<=", "le")):
            if isinstance(meta, cls):
                out.append(f"{op} {getattr(meta, attr):g}")
    return out


def _path_error(path: str, message: str, allowed: str) -> ProfileError:
    return ProfileError(message, source="--param", field=path, allowed=allowed)


def resolve_path(path: str) -> PathInfo:
    """Check a dotted parameter path against the profile models.

    Parameters
    ----------
    path
        ``PART.KEY[.KEY...]`` (see the module docstring) or a documented alias.

    Returns
    -------
    PathInfo

    Raises
    ------
    ProfileError
        The part or a key does not exist, or the path names a table instead of a value.
    """
    canonical = ALIASES.get(path, path)
    parts = canonical.split(".")
    head = parts[0]
    if head not in PARTS:
        hint = _HINTS.get(head)
        raise _path_error(path, "unknown profile part" + (f" ({hint})" if hint else ""),
                          "a path starting with one of " + ", ".join(PARTS))
    if len(parts) < 2 or not all(parts[1:]):
        raise _path_error(path, "a parameter path needs a key after the part",
                          f"{head}.<key>, keys: " + ", ".join(PARTS[head].model_fields))
    annotation: Any = PARTS[head]
    field_bounds: list[str] = []
    for depth, key in enumerate(parts[1:], start=1):
        models = [c for c in _candidates(annotation) if _is_model(c)]
        owner = next((m for m in models if key in m.model_fields), None)
        if owner is None:
            known = sorted({k for m in models for k in m.model_fields})
            where = ".".join(parts[:depth])
            hint = _HINTS.get(key)
            if not models:
                raise _path_error(path, f"{where} is a value, not a table", f"the path {where}")
            raise _path_error(path, f"{where} has no key {key!r}" + (f" ({hint})" if hint
                                                                      else ""),
                              "keys: " + ", ".join(known))
        info = owner.model_fields[key]
        annotation = info.annotation
        field_bounds = _bounds(info)
    leaf = _candidates(annotation)
    if any(_is_model(c) for c in leaf) or any(typing.get_origin(c) in (list, tuple)
                                               for c in leaf):
        raise _path_error(path, "names a table, not a value",
                          "a key inside it, e.g. " + canonical + ".<key>")
    choices: tuple[str, ...] = ()
    kind: ValueKind
    if bool in leaf:
        kind = "bool"
    elif int in leaf and float not in leaf:
        kind = "int"
    elif float in leaf:
        kind = "float"
    elif str in leaf:
        kind = "str"
    elif leaf and typing.get_origin(leaf[0]) is Literal:
        kind = "str"
        choices = tuple(str(v) for v in typing.get_args(leaf[0]))
    elif leaf and isinstance(leaf[0], type) and issubclass(leaf[0], enum.Enum):
        kind = "str"  # e.g. the printer's firmware (flowtwin.firmware.Firmware)
        choices = tuple(str(m.value) for m in leaf[0])
    else:  # pragma: no cover - every profile field is one of the above
        raise _path_error(path, "has a type that cannot be swept", "a number, flag or name")
    allowed = (" and ".join(field_bounds) if field_bounds
               else "one of " + ", ".join(choices) if choices
               else {"bool": "true or false", "str": "a name", "int": "an integer",
                     "float": "a number"}[kind])
    return PathInfo(canonical, head, tuple(parts[1:]), kind, choices, allowed)


def describe_path(path: str) -> str:
    """One line: the canonical path, its type and its declared range."""
    info = resolve_path(path)
    return f"{info.path} ({info.kind}; allowed: {info.allowed})"


def _decimal(text: str, axis_text: str, path: str) -> Decimal:
    try:
        value = Decimal(text.strip())
    except InvalidOperation:
        value = Decimal("NaN")
    if not value.is_finite():
        raise ProfileError("not a number", source="--param", field=path, value=text,
                           allowed=f"numbers in {axis_text!r}")
    return value


def _convert(text: str, info: PathInfo, path: str) -> ParamValue:
    raw = text.strip()
    if info.kind == "bool":
        low = raw.lower()
        if low in ("true", "1", "yes", "on"):
            return True
        if low in ("false", "0", "no", "off"):
            return False
        raise ProfileError("not a flag", source="--param", field=path, value=raw,
                           allowed="true or false")
    if info.kind == "str":
        if not raw:
            raise ProfileError("empty value", source="--param", field=path, value=raw,
                               allowed=info.allowed)
        if info.choices and raw not in info.choices:
            raise ProfileError("not one of the allowed choices", source="--param", field=path,
                               value=raw, allowed=info.allowed)
        return raw
    number = _decimal(raw, raw, path)
    if info.kind == "int":
        if number != number.to_integral_value():
            raise ProfileError("must be an integer", source="--param", field=path,
                               value=raw, allowed=info.allowed)
        return int(number)
    return float(number)


def _range(text: str, info: PathInfo, path: str) -> list[ParamValue]:
    pieces = text.split(":")
    if len(pieces) != 3:
        raise ProfileError("a range needs start:stop:step", source="--param", field=path,
                           value=text, allowed="a:b:step (inclusive), a,b,c, or a:b "
                                               "with --sample")
    start, stop, step = (_decimal(p, text, path) for p in pieces)
    if step == 0 or (stop - start) * step < 0:
        raise ProfileError("the step must be non-zero and go from start towards stop",
                           source="--param", field=path, value=text,
                           allowed="a:b:step with step > 0 for a <= b (< 0 for a > b)")
    count = int((stop - start) / step) + 1  # Decimal: exact for decimal inputs
    if count > MAX_GRID_POINTS:
        raise ProfileError("the range has too many values", source="--param", field=path,
                           value=text, allowed=f"at most {MAX_GRID_POINTS:,} values")
    values = [start + i * step for i in range(count)]
    if info.kind == "int":
        if any(v != v.to_integral_value() for v in values):
            raise ProfileError("an integer key needs an integer range", source="--param",
                               field=path, value=text, allowed=info.allowed)
        return [int(v) for v in values]
    return [float(v) for v in values]


def parse_axis(text: str, *, sampling: bool = False) -> Axis:
    """Parse one ``--param PATH=VALUES`` option.

    Parameters
    ----------
    text
        ``PATH=VALUES`` with ``PATH`` a dotted path (or several joined by ``+``) and
        ``VALUES`` a range ``a:b:step``, a list ``a,b,c``, or (with ``sampling``) an
        interval ``a:b``.
    sampling
        Random sampling is requested, so ``a:b`` intervals are allowed.

    Returns
    -------
    Axis

    Raises
    ------
    ProfileError
        Bad syntax, unknown path, or a value of the wrong type; the message names the
        parameter, the value and what is allowed. Range checks against the profile's
        declared bounds happen when the values are applied to a machine
        (:func:`flowtwin.batch.overrides.check_axes`).
    """
    if "=" not in text:
        raise ProfileError("a parameter needs PATH=VALUES", source="--param", value=text,
                           allowed="e.g. setup.temperature_c=190:230:5")
    lhs, rhs = text.split("=", 1)
    names = [p.strip() for p in lhs.split("+")]
    infos = [resolve_path(p) for p in names]
    kinds = {i.kind for i in infos}
    if len(kinds) > 1:
        raise ProfileError("linked paths must take the same kind of value", source="--param",
                           field=lhs, value=sorted(kinds), allowed="paths of one type")
    if len({i.path for i in infos}) != len(infos):
        raise ProfileError("a path is linked to itself", source="--param", field=lhs)
    info = infos[0]
    paths = tuple(i.path for i in infos)
    label = "+".join(paths)
    rhs = rhs.strip()
    if not rhs:
        raise ProfileError("no values given", source="--param", field=label,
                           allowed="a:b:step, a,b,c or (with --sample) a:b")
    if info.kind in ("float", "int") and ":" in rhs:
        if rhs.count(":") == 1:
            if not sampling:
                raise ProfileError("an interval a:b needs random sampling (--sample N)",
                                   source="--param", field=label, value=rhs,
                                   allowed="a:b:step or a,b,c for a grid")
            lo_text, hi_text = rhs.split(":")
            lo, hi = _decimal(lo_text, rhs, label), _decimal(hi_text, rhs, label)
            if not lo < hi:
                raise ProfileError("an interval needs low < high", source="--param",
                                   field=label, value=rhs, allowed="a:b with a < b")
            return Axis(paths, info.kind, (), (float(lo), float(hi)), text)
        values = _range(rhs, info, label)
    else:
        values = [_convert(v, info, label) for v in rhs.split(",")]
    unique = list(dict.fromkeys(values))
    if len(unique) != len(values):
        raise ProfileError("a value is repeated", source="--param", field=label, value=rhs,
                           allowed="distinct values")
    for v in unique:
        if isinstance(v, float) and not math.isfinite(v):  # pragma: no cover - Decimal checked
            raise ProfileError("not a finite number", source="--param", field=label, value=v)
    return Axis(paths, info.kind, tuple(unique), None, text)
