"""Turn pydantic validation errors into :class:`~flowtwin.errors.ProfileError`.

The message names the file, the dotted key, the value and what is allowed, with the allowed
range taken from the field's declared bounds or ``Literal`` choices, e.g.::

    printer.toml [limits.max_accel_mm_s2]: must be > 0; got -5.0; allowed: > 0 and <= 1e+06

Unknown keys name the key, suggest the closest known one and list the allowed keys.
"""

from __future__ import annotations

import difflib
import enum
import types
import typing
from dataclasses import dataclass
from typing import Any, Literal, TypeVar

import annotated_types as at
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from flowtwin.errors import ProfileError

__all__ = ["Problem", "ProfileValidationError", "profile_error_from_validation",
           "validate_model"]

M = TypeVar("M", bound=BaseModel)


@dataclass(frozen=True, slots=True)
class Problem:
    """One validation problem: dotted key, message, offending value and what is allowed."""

    key: str
    message: str
    value: object
    allowed: str | None


class ProfileValidationError(ProfileError):
    """A :class:`ProfileError` from schema validation; ``problems`` lists every problem.

    The exception's own ``field``/``value``/``allowed`` describe the first problem.
    """

    problems: tuple[Problem, ...] = ()


def validate_model(model: type[M], data: object, *, source: str | None = None) -> M:
    """Validate ``data`` against ``model``; raise :class:`ProfileValidationError` if invalid.

    Parameters
    ----------
    model
        The pydantic model class.
    data
        Parsed TOML (a dict) or any object.
    source
        File name (or other origin) for the error message.
    """
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise profile_error_from_validation(exc, model, source=source) from exc


def profile_error_from_validation(exc: ValidationError, model: type[BaseModel], *,
                                  source: str | None = None) -> ProfileValidationError:
    """Build the :class:`ProfileValidationError` for a pydantic ``ValidationError``."""
    raw = exc.errors()
    problems_list = [_problem(err, model) for err in raw]
    # A list whose entry failed is also reported as too short: keep only the entry's error.
    problems_list = [
        p for p, err in zip(problems_list, raw, strict=True)
        if not (err.get("type") == "too_short"
                and any(q.key.startswith(p.key + "[") for q in problems_list))]
    # Unknown keys first: a misspelt key also shows up as a missing required key.
    problems_list.sort(key=lambda p: 0 if p.message.startswith("unknown key") else 1)
    problems = tuple(problems_list)
    if not problems:  # pragma: no cover - pydantic always reports at least one error
        problems = (Problem("", str(exc), None, None),)
    first = problems[0]
    message = first.message
    if len(problems) > 1:
        others = [p.key or "<top level>" for p in problems[1:]]
        shown = ", ".join(others[:6]) + (", ..." if len(others) > 6 else "")
        message += f" (and {len(others)} more problem{'s' if len(others) > 1 else ''}: " \
                   f"{shown})"
    err = ProfileValidationError(message, source=source, field=first.key or None,
                                 value=first.value, allowed=first.allowed)
    err.problems = problems
    return err


# --- walking the model along an error location ---------------------------------------

def _candidates(annotation: Any) -> list[Any]:
    """Flatten Optional/Union/Annotated into the list of member types (None dropped)."""
    if annotation is None:
        return []
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


def _tag_of(model: type[BaseModel]) -> str | None:
    """The ``law``-style discriminator value of a union member, if it has one."""
    for field in model.model_fields.values():
        args = _candidates(field.annotation)
        if len(args) == 1 and typing.get_origin(args[0]) is Literal:
            values = typing.get_args(args[0])
            if len(values) == 1 and isinstance(values[0], str):
                return values[0]
    return None


@dataclass
class _Where:
    key: str
    field: FieldInfo | None
    annotation: Any
    parent: type[BaseModel] | None


def _walk(loc: tuple[int | str, ...], model: type[BaseModel]) -> _Where:
    parts: list[str] = []
    annotation: Any = model
    field: FieldInfo | None = None
    parent: type[BaseModel] | None = model
    for item in loc:
        cands = _candidates(annotation)
        if isinstance(item, int):
            inner = None
            for c in cands:
                if typing.get_origin(c) in (tuple, list):
                    args = [a for a in typing.get_args(c) if a is not Ellipsis]
                    inner = args[0] if args else None
                    break
            if parts:
                parts[-1] += f"[{item}]"
            else:
                parts.append(f"[{item}]")
            annotation, field = inner, None
            continue
        models = [c for c in cands if _is_model(c)]
        owner = next((m for m in models if item in m.model_fields), None)
        if owner is None:
            tagged = [m for m in models if _tag_of(m) == item or m.__name__ == item]
            if tagged and len(models) > 1:
                annotation = tagged[0]  # union member selected by its tag: not a key
                parent = tagged[0]
                continue
            parts.append(str(item))
            parent = models[0] if models else None
            annotation, field = None, None
            continue
        parent = owner
        field = owner.model_fields[item]
        parts.append(item)
        annotation = field.annotation
    return _Where(".".join(parts), field, annotation, parent)


def _fmt(number: object) -> str:
    return f"{number:g}" if isinstance(number, float) else str(number)


def _bounds(field: FieldInfo | None) -> list[str]:
    if field is None:
        return []
    out: list[str] = []
    for meta in field.metadata:
        if isinstance(meta, at.Gt):
            out.append(f"> {_fmt(meta.gt)}")
        elif isinstance(meta, at.Ge):
            out.append(f">= {_fmt(meta.ge)}")
        elif isinstance(meta, at.Lt):
            out.append(f"< {_fmt(meta.lt)}")
        elif isinstance(meta, at.Le):
            out.append(f"<= {_fmt(meta.le)}")
    return out


def _allowed(where: _Where) -> str | None:
    """Describe what the field at ``where`` accepts."""
    bounds = _bounds(where.field)
    cands = _candidates(where.annotation)
    kinds: list[str] = []
    for c in cands:
        if typing.get_origin(c) is Literal:
            kinds.append("one of " + ", ".join(repr(v) for v in typing.get_args(c)))
        elif isinstance(c, type) and issubclass(c, enum.Enum):
            kinds.append("one of " + ", ".join(repr(m.value) for m in c))
        elif c is bool:
            kinds.append("true or false")
        elif c is int:
            kinds.append("an integer")
        elif c is float:
            kinds.append("a number")
        elif c is str:
            kinds.append("a string")
        elif _is_model(c):
            tag = _tag_of(c)
            kinds.append(f"a table with law = {tag!r}" if tag else "a table")
        elif typing.get_origin(c) in (tuple, list):
            kinds.append("an array of tables")
    if bounds:
        return " and ".join(bounds)
    if where.field is not None:
        for meta in where.field.metadata:
            if isinstance(meta, at.MinLen) and meta.min_length:
                unit = "characters" if str in cands else "entries"
                kinds.append(f"at least {meta.min_length} {unit}")
    return ", ".join(dict.fromkeys(kinds)) or None


def _known_keys(parent: type[BaseModel] | None) -> list[str]:
    return list(parent.model_fields) if parent is not None else []


def _problem(err: Any, model: type[BaseModel]) -> Problem:
    loc: tuple[int | str, ...] = tuple(err.get("loc", ()))
    kind: str = err.get("type", "")
    ctx: dict[str, Any] = err.get("ctx") or {}
    value: object = err.get("input")
    where = _walk(loc, model)
    allowed = _allowed(where)
    if kind == "extra_forbidden":
        bad = str(loc[-1]) if loc else "?"
        known = _known_keys(where.parent)
        close = difflib.get_close_matches(bad, known, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return Problem(where.key, f"unknown key {bad!r}{hint}", value,
                       "known keys: " + ", ".join(known) if known else None)
    if kind == "missing":
        return Problem(where.key, "missing required key", None, allowed)
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        disc = str(ctx.get("discriminator", "law")).strip("'")
        tags = [_tag_of(c) for c in _candidates(where.annotation) if _is_model(c)]
        tag_text = ", ".join(repr(t) for t in tags if t) or str(ctx.get("expected_tags", ""))
        if kind == "union_tag_not_found":
            return Problem(where.key, f"needs the key {disc!r} to choose its kind", None,
                           f"{disc} = one of {tag_text}")
        return Problem(where.key, f"unknown {disc}", ctx.get("tag"),
                       f"{disc} = one of {tag_text}")
    simple = {
        "greater_than": lambda: f"must be > {_fmt(ctx.get('gt'))}",
        "greater_than_equal": lambda: f"must be >= {_fmt(ctx.get('ge'))}",
        "less_than": lambda: f"must be < {_fmt(ctx.get('lt'))}",
        "less_than_equal": lambda: f"must be <= {_fmt(ctx.get('le'))}",
        "finite_number": lambda: "must be a finite number (no inf or nan)",
        "float_type": lambda: "must be a number",
        "float_parsing": lambda: "must be a number",
        "int_type": lambda: "must be an integer",
        "int_parsing": lambda: "must be an integer",
        "int_from_float": lambda: "must be an integer",
        "bool_type": lambda: "must be true or false",
        "bool_parsing": lambda: "must be true or false",
        "string_type": lambda: "must be a string",
        "string_too_short": lambda: "must not be empty" if ctx.get("min_length") == 1
        else f"must have at least {ctx.get('min_length')} characters",
        "string_too_long": lambda: f"must have at most {ctx.get('max_length')} characters",
        "string_pattern_mismatch": lambda: f"must match the pattern {ctx.get('pattern')}",
        "literal_error": lambda: "is not one of the allowed choices",
        "enum": lambda: "is not one of the allowed choices",
        "model_type": lambda: "must be a table",
        "model_attributes_type": lambda: "must be a table",
        "dict_type": lambda: "must be a table",
        "tuple_type": lambda: "must be an array",
        "list_type": lambda: "must be an array",
        "too_short": lambda: f"must have at least {ctx.get('min_length')} entries",
        "too_long": lambda: f"must have at most {ctx.get('max_length')} entries",
    }
    if kind in simple:
        if kind in ("too_short", "too_long"):
            value = None
        return Problem(where.key, simple[kind](), value, allowed)
    if kind in ("value_error", "assertion_error"):
        msg = str(err.get("msg", "invalid value"))
        for prefix in ("Value error, ", "Assertion failed, "):
            if msg.startswith(prefix):
                msg = msg[len(prefix):]
        # the input of a model-level check is the whole table: do not echo it
        shown = None if isinstance(value, dict) else value
        return Problem(where.key, msg, shown, None if isinstance(value, dict) else allowed)
    return Problem(where.key, str(err.get("msg", "invalid value")), value, allowed)
