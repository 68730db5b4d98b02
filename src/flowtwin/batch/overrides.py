"""Apply parameter values to a machine, and enumerate the points of a sweep.

Every value goes through the profile models' own validation (declared bounds, model
checks) and through the fit checks of :func:`flowtwin.profiles.load_machine` (nozzle of the
firmware = nozzle of the hot end, filament fits the bore, temperature inside the viscosity
law's range, pinch force inside the roller's fit), so a sweep point is exactly as valid as
a profile written by hand. A bad value is a :class:`~flowtwin.errors.ProfileError` that
names the parameter path, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
from pydantic import BaseModel

from flowtwin.batch.options import DEFAULT_SETUP
from flowtwin.batch.params import MAX_GRID_POINTS, PARTS, Axis, ParamValue, resolve_path
from flowtwin.errors import ProfileError
from flowtwin.profiles import machine as _machine_module
from flowtwin.profiles.library import load_rollers
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.profiles.toml_io import load_profile
from flowtwin.profiles.validation import validate_model

__all__ = [
    "DEFAULT_SETUP",
    "MachineBuilder",
    "check_axes",
    "count_points",
    "grid_points",
    "load_base",
    "point_overrides",
    "sample_points",
]

_REFS = ("printer", "drive", "hotend", "material", "filament")

# Which parameter a failed fit check of load_machine is about.
_FIT_FIELDS = {"temperature_c": "setup.temperature_c", "drive": "drive.pinch_force_n",
               "hotend": "hotend.nozzle_diameter_mm", "filament": "filament.diameter_mm"}


def load_base(profile: str | os.PathLike[str] | SetupProfile | Machine | None) -> Machine:
    """Resolve the machine a batch or sweep starts from.

    Parameters
    ----------
    profile
        A :class:`Machine`, a :class:`SetupProfile`, a built-in set-up name or a set-up
        ``.toml`` path; ``None`` for :data:`DEFAULT_SETUP`.

    Returns
    -------
    Machine
        The machine; for a set-up file its ``.toml`` part references are made absolute, so
        a ``setup.<part>`` sweep can load other parts from any working directory.
    """
    if isinstance(profile, Machine):
        return profile
    if profile is None:
        profile = DEFAULT_SETUP
    machine = load_machine(profile)
    if isinstance(profile, SetupProfile):
        return machine
    text = os.fspath(profile)
    if text.endswith(".toml") or Path(text).is_file():
        folder = Path(text).resolve().parent
        setup = load_profile(text, "setup")
        assert isinstance(setup, SetupProfile)
        refs = {k: str(folder / getattr(setup, k)) for k in _REFS
                if getattr(setup, k).endswith(".toml")
                and not Path(getattr(setup, k)).is_absolute()}
        if refs:
            machine = dataclasses.replace(machine, setup=setup.model_copy(update=refs))
    return machine


def point_overrides(axes: Sequence[Axis], values: Sequence[ParamValue]) -> dict[str, ParamValue]:
    """The path -> value mapping of one point (linked paths all get the axis value)."""
    out: dict[str, ParamValue] = {}
    for axis, value in zip(axes, values, strict=True):
        for path in axis.paths:
            out[path] = value
    return out


def _describe(overrides: Mapping[str, ParamValue]) -> str:
    return ", ".join(f"{k}={v}" for k, v in overrides.items())


class MachineBuilder:
    """Builds the machine of each sweep point from a base machine.

    Validated parts are cached by their overrides, so a grid of many points costs one
    validation per distinct part and a fit check per point.

    Parameters
    ----------
    base
        The machine the overrides apply to.
    max_cache
        Cached parts kept at most (the cache is emptied when it is full).
    """

    def __init__(self, base: Machine, *, max_cache: int = 4096) -> None:
        self.base = base
        self._max_cache = max_cache
        self._parts: dict[tuple[str, tuple[tuple[str, ParamValue], ...]], object] = {}
        self._rollers = load_rollers()

    def _part(self, part: str, obj: BaseModel, items: tuple[tuple[str, ParamValue], ...],
              context: Mapping[str, ParamValue]) -> BaseModel:
        key = (part, items)
        hit = self._parts.get(key)
        if hit is not None:
            assert isinstance(hit, BaseModel)
            return hit
        data = obj.model_dump()
        for path, value in items:
            node = data
            keys = path.split(".")[1:]
            for k in keys[:-1]:
                if node.get(k) is None:
                    node[k] = {}
                node = node[k]
            node[keys[-1]] = value
        try:
            new = validate_model(PARTS[part], data, source="--param")
        except ProfileError as exc:
            field = f"{part}.{exc.field}" if exc.field else part
            given: dict[str, object] = dict(items)
            shown = given.get(field, exc.value)
            extra = f" (point: {_describe(context)})" if len(context) > 1 else ""
            raise ProfileError(f"{exc.message}{extra}", source="--param", field=field,
                               value=shown, allowed=exc.allowed) from exc
        if len(self._parts) >= self._max_cache:
            self._parts.clear()
        self._parts[key] = new
        return new

    def build(self, overrides: Mapping[str, ParamValue]) -> Machine:
        """The base machine with ``overrides`` (canonical path -> value) applied.

        Raises
        ------
        ProfileError
            A value is outside its declared range, makes a part inconsistent, or makes the
            parts not fit together; names the parameter, the value and what is allowed.
        """
        if not overrides:
            return self.base
        grouped: dict[str, list[tuple[str, ParamValue]]] = {}
        for path, value in overrides.items():
            info = resolve_path(path)
            grouped.setdefault(info.part, []).append((info.path, value))
        machine = self.base
        if "setup" in grouped:
            items = tuple(sorted(grouped.pop("setup")))
            setup = self._part("setup", machine.setup, items, overrides)
            assert isinstance(setup, SetupProfile)
            if any(path.split(".")[1] in _REFS for path, _ in items):
                try:
                    machine = load_machine(setup)
                except ProfileError as exc:
                    where = f" (point: {_describe(overrides)})" if len(overrides) > 1 else ""
                    raise ProfileError(f"{exc.message}{where}",
                                       source="--param", field=f"setup.{exc.field}",
                                       value=exc.value, allowed=exc.allowed) from exc
            else:
                machine = dataclasses.replace(machine, setup=setup)
        changes: dict[str, object] = {}
        for part, entries in grouped.items():
            changes[part] = self._part(part, getattr(machine, part), tuple(sorted(entries)),
                                       overrides)
        if changes:
            machine = dataclasses.replace(machine, **changes)  # type: ignore[arg-type]
        if "drive" in changes:
            try:
                roller = machine.drive.resolve_roller(self._rollers)
            except ProfileError as exc:
                raise ProfileError(exc.message, source="--param",
                                   field=f"drive.{exc.field}" if exc.field else "drive",
                                   value=exc.value, allowed=exc.allowed) from exc
            machine = dataclasses.replace(machine, roller=roller)
        try:
            # The fit checks of load_machine (flowtwin.profiles.machine), run on the new parts.
            _machine_module.check_machine(machine, "--param")
        except ProfileError as exc:
            field = _FIT_FIELDS.get(exc.field or "", exc.field)
            where = f" (point: {_describe(overrides)})" if len(overrides) > 1 else ""
            given_all: dict[str, object] = dict(overrides)
            raise ProfileError(f"{exc.message}{where}", source="--param", field=field,
                               value=given_all.get(field or "", exc.value),
                               allowed=exc.allowed) from exc
        return machine


def check_axes(builder: MachineBuilder, axes: Sequence[Axis]) -> None:
    """Apply every value of every axis alone to the base machine (ends of an interval).

    Run before the points are built so that a bad value is reported by itself, not as
    part of a combination.

    Raises
    ------
    ProfileError
        Naming the parameter, the value and what is allowed.
    """
    for axis in axes:
        values: Sequence[ParamValue] = axis.values
        if axis.interval is not None:
            lo, hi = axis.interval
            values = ((math.ceil(lo), math.floor(hi)) if axis.kind == "int" else (lo, hi))
        for value in values:
            builder.build(point_overrides([axis], [value]))


def count_points(axes: Sequence[Axis]) -> int:
    """Number of points of the full grid of ``axes`` (1 for no axes)."""
    total = 1
    for axis in axes:
        if axis.size is None:
            raise ProfileError("an interval a:b cannot be gridded", source="--param",
                               field=axis.name, value=axis.text,
                               allowed="a:b:step or a,b,c, or sample with --sample N")
        total *= axis.size
    return total


def grid_points(axes: Sequence[Axis]) -> Iterator[dict[str, ParamValue]]:
    """Every point of the grid, the first axis varying slowest.

    Raises
    ------
    ProfileError
        The grid has more than :data:`~flowtwin.batch.params.MAX_GRID_POINTS` points.
    """
    total = count_points(axes)
    if total > MAX_GRID_POINTS:
        raise ProfileError("the grid is too large", source="--param",
                           field=" × ".join(a.name for a in axes), value=total,
                           allowed=f"at most {MAX_GRID_POINTS:,} points; use --sample N")
    for combo in itertools.product(*(a.values for a in axes)):
        yield point_overrides(axes, combo)


def _item(value: object) -> ParamValue:
    """numpy scalar -> Python scalar."""
    if isinstance(value, np.generic):
        out = value.item()
        assert isinstance(out, float | int | bool | str)
        return out
    assert isinstance(value, float | int | bool | str)
    return value


def sample_points(axes: Sequence[Axis], n: int, *, seed: int) -> list[dict[str, ParamValue]]:
    """``n`` random points of the parameter space, reproducible from ``seed``.

    With only discrete axes the points are drawn from the grid without replacement (and
    returned in grid order); with an interval every axis is drawn independently (uniform
    over a list, uniform over an interval, integers inclusive), and repeated points are
    dropped.

    Parameters
    ----------
    axes
        The parameters.
    n
        Number of points wanted (>= 1).
    seed
        Seed of :func:`numpy.random.default_rng`.

    Raises
    ------
    ProfileError
        ``n`` < 1, or more points asked for than a discrete grid has.
    """
    if n < 1:
        raise ProfileError("the sample size must be positive", field="--sample", value=n,
                           allowed=">= 1")
    rng = np.random.default_rng(seed)
    if all(a.size is not None for a in axes):
        total = math.prod(a.size or 0 for a in axes)
        if n > total:
            raise ProfileError("more samples than grid points", field="--sample", value=n,
                               allowed=f"<= {total} (the grid of the discrete values)")
        if total >= 2 ** 62:
            raise ProfileError("the grid is too large to sample without replacement",
                               field="--sample", value=total, allowed="< 2**62 points")
        flat = np.sort(rng.choice(total, size=n, replace=False))
        index = np.unravel_index(flat, tuple(a.size or 0 for a in axes))
        return [point_overrides(axes, [_item(a.values[int(ix[k])])
                                       for a, ix in zip(axes, index, strict=True)])
                for k in range(n)]
    columns: list[list[ParamValue]] = []
    for a in axes:
        if a.interval is None:
            picks = rng.integers(0, len(a.values), size=n)
            columns.append([a.values[int(i)] for i in picks])
        elif a.kind == "int":
            lo, hi = math.ceil(a.interval[0]), math.floor(a.interval[1])
            columns.append([int(v) for v in rng.integers(lo, hi + 1, size=n)])
        else:
            columns.append([float(v) for v in rng.uniform(*a.interval, size=n)])
    points: dict[tuple[ParamValue, ...], dict[str, ParamValue]] = {}
    for k in range(n):
        combo = tuple(col[k] for col in columns)
        points.setdefault(combo, point_overrides(axes, combo))
    return list(points.values())
