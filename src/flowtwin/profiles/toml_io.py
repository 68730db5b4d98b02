"""Read and write profiles as TOML.

A profile file is one TOML document whose top-level keys are the profile's fields, plus an
optional ``kind = "printer"`` (``drive``, ``hotend``, ``material``, ``filament``, ``setup``,
``roller``, ``roller_table``) that says which schema it follows. Every problem — unreadable
file, malformed TOML, unknown key, value out of range — raises
:class:`~flowtwin.errors.ProfileError` naming the file, the line or dotted key, the value
and what is allowed.
"""

from __future__ import annotations

import os
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Literal, TypeAlias, overload

import tomli_w
from pydantic import BaseModel

from flowtwin.atomic import atomic_write_text
from flowtwin.errors import ProfileError
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.filament import FilamentProfile
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.profiles.material import MaterialProfile
from flowtwin.profiles.printer import PrinterProfile
from flowtwin.profiles.rollers import Roller, RollerTable
from flowtwin.profiles.setup import SetupProfile
from flowtwin.profiles.validation import validate_model

__all__ = [
    "KIND_MODELS",
    "Profile",
    "ProfileKind",
    "kind_of",
    "load_profile",
    "profile_from_dict",
    "profile_from_toml",
    "profile_to_toml",
    "save_profile",
]

ProfileKind: TypeAlias = Literal["printer", "drive", "hotend", "material", "filament",
                                 "setup", "roller", "roller_table"]

Profile: TypeAlias = (PrinterProfile | DriveProfile | HotendProfile | MaterialProfile
                      | FilamentProfile | SetupProfile | Roller | RollerTable)

#: Schema of each kind.
KIND_MODELS: Mapping[str, type[BaseModel]] = {
    "printer": PrinterProfile,
    "drive": DriveProfile,
    "hotend": HotendProfile,
    "material": MaterialProfile,
    "filament": FilamentProfile,
    "setup": SetupProfile,
    "roller": Roller,
    "roller_table": RollerTable,
}

_KIND_OF_MODEL = {model: kind for kind, model in KIND_MODELS.items()}
_TOML_POSITION = re.compile(r"\s*\(at line (\d+), column (\d+)\)\s*$")
_TOML_END = re.compile(r"\s*\(at end of document\)\s*$")


def kind_of(profile: BaseModel) -> ProfileKind:
    """Return the kind name of a profile object (e.g. ``"printer"``)."""
    try:
        return _KIND_OF_MODEL[type(profile)]  # type: ignore[return-value]
    except KeyError:
        raise TypeError(f"{type(profile).__name__} is not a profile model") from None


def _allowed_kinds() -> str:
    return ", ".join(repr(k) for k in KIND_MODELS)


def profile_from_dict(data: Mapping[str, object], kind: ProfileKind | None = None, *,
                      source: str | os.PathLike[str] | None = None) -> Profile:
    """Validate a parsed TOML table as a profile.

    Parameters
    ----------
    data
        Top-level table. An optional ``kind`` key names the schema; it must agree with
        ``kind`` when both are given.
    kind
        Schema to validate against; None takes it from ``data["kind"]``.
    source
        File name for error messages.

    Returns
    -------
    Profile
        The validated, frozen profile object.

    Raises
    ------
    ProfileError
        Unknown or missing kind, unknown key, wrong type, value out of range.
    """
    src = None if source is None else str(source)
    if not isinstance(data, Mapping):
        raise ProfileError("a profile must be a TOML table", source=src,
                           value=type(data).__name__, allowed="a table of keys")
    body = dict(data)
    file_kind = body.pop("kind", None)
    if file_kind is not None:
        if not isinstance(file_kind, str) or file_kind not in KIND_MODELS:
            raise ProfileError("unknown profile kind", source=src, field="kind",
                               value=file_kind, allowed=_allowed_kinds())
        if kind is not None and file_kind != kind:
            raise ProfileError(f"the file holds a {file_kind} profile, not a {kind} profile",
                               source=src, field="kind", value=file_kind, allowed=repr(kind))
    chosen = kind if kind is not None else file_kind
    if chosen is None:
        raise ProfileError("cannot tell which kind of profile this is: add a top-level "
                           "'kind' key", source=src, field="kind", allowed=_allowed_kinds())
    if chosen not in KIND_MODELS:
        raise ProfileError("unknown profile kind", source=src, field="kind", value=chosen,
                           allowed=_allowed_kinds())
    result = validate_model(KIND_MODELS[chosen], body, source=src)
    return result  # type: ignore[return-value]


def profile_from_toml(text: str, kind: ProfileKind | None = None, *,
                      source: str | os.PathLike[str] | None = None) -> Profile:
    """Parse TOML text and validate it as a profile (see :func:`profile_from_dict`).

    Raises
    ------
    ProfileError
        Malformed TOML (with line and column) or an invalid profile.
    """
    src = None if source is None else str(source)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        line = None
        match = _TOML_POSITION.search(message)
        if match:
            line = int(match.group(1))
            message = message[:match.start()] + f" (column {match.group(2)})"
        else:
            end = _TOML_END.search(message)
            if end:
                message = message[:end.start()] + " (at end of file)"
        raise ProfileError(f"malformed TOML: {message}", source=src, line=line) from exc
    except RecursionError as exc:
        raise ProfileError("malformed TOML: nesting too deep", source=src) from exc
    return profile_from_dict(data, kind, source=src)


@overload
def load_profile(path: str | os.PathLike[str], kind: Literal["printer"]) -> PrinterProfile: ...
@overload
def load_profile(path: str | os.PathLike[str], kind: Literal["drive"]) -> DriveProfile: ...
@overload
def load_profile(path: str | os.PathLike[str], kind: Literal["hotend"]) -> HotendProfile: ...
@overload
def load_profile(path: str | os.PathLike[str],
                 kind: Literal["material"]) -> MaterialProfile: ...
@overload
def load_profile(path: str | os.PathLike[str],
                 kind: Literal["filament"]) -> FilamentProfile: ...
@overload
def load_profile(path: str | os.PathLike[str], kind: Literal["setup"]) -> SetupProfile: ...
@overload
def load_profile(path: str | os.PathLike[str], kind: Literal["roller"]) -> Roller: ...
@overload
def load_profile(path: str | os.PathLike[str],
                 kind: Literal["roller_table"]) -> RollerTable: ...
@overload
def load_profile(path: str | os.PathLike[str], kind: None = None) -> Profile: ...


def load_profile(path: str | os.PathLike[str], kind: ProfileKind | None = None) -> Profile:
    """Load a profile from a TOML file.

    Parameters
    ----------
    path
        The ``.toml`` file.
    kind
        Expected kind; None accepts whatever the file's ``kind`` key says.

    Raises
    ------
    ProfileError
        Unreadable file, not UTF-8, malformed TOML or invalid profile.
    """
    src = str(path)
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise ProfileError(f"cannot read profile: {exc.strerror or exc}", source=src) from exc
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ProfileError("profile is not UTF-8 text", source=src, line=line) from exc
    return profile_from_toml(text, kind, source=src)


def profile_to_toml(profile: BaseModel) -> str:
    """TOML text of a profile (with its ``kind``); unset optional keys are left out."""
    data: dict[str, object] = {"kind": kind_of(profile)}
    data.update(profile.model_dump(mode="json", exclude_none=True))
    return tomli_w.dumps(data)


def save_profile(profile: BaseModel, path: str | os.PathLike[str]) -> None:
    """Write a profile to ``path`` as TOML, atomically (comments are not preserved).

    ``load_profile(path)`` returns an equal object.
    """
    atomic_write_text(path, profile_to_toml(profile))
