"""The built-in profile library shipped in ``flowtwin/data``.

Layout (package data)::

    data/rollers.toml            the seven rollers of [000] (kind roller_table)
    data/printers/<name>.toml    kind printer
    data/drives/<name>.toml      kind drive
    data/hotends/<name>.toml     kind hotend
    data/materials/<name>.toml   kind material
    data/filaments/<name>.toml   kind filament
    data/setups/<name>.toml      kind setup

Each file's name is its profile's ``name``. Names are unique across kinds. The roller table
is listed as ``rollers`` and each of its rows as ``roller-1`` … ``roller-7``.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from importlib import resources
from importlib.resources.abc import Traversable

from flowtwin.errors import ProfileError
from flowtwin.profiles.rollers import Roller, RollerTable
from flowtwin.profiles.toml_io import Profile, ProfileKind, profile_from_toml

__all__ = [
    "LibraryEntry",
    "library_entries",
    "library_names",
    "load_builtin",
    "load_roller_table",
    "load_rollers",
]

ROLLER_TABLE_NAME = "rollers"
_ROLLER_FILE = "rollers.toml"
_FOLDERS: dict[str, ProfileKind] = {
    "printers": "printer",
    "drives": "drive",
    "hotends": "hotend",
    "materials": "material",
    "filaments": "filament",
    "setups": "setup",
}


@dataclass(frozen=True, slots=True)
class LibraryEntry:
    """One built-in profile: its name, kind, one-line description and data file."""

    name: str
    kind: ProfileKind
    description: str
    resource: str


def _data_root() -> Traversable:
    return resources.files("flowtwin") / "data"


def _label(*parts: str) -> str:
    return "flowtwin/data/" + "/".join(parts)


def _read(item: Traversable, label: str, kind: ProfileKind) -> Profile:
    try:
        text = item.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:  # a broken installation
        raise ProfileError(f"cannot read built-in profile: {exc}", source=label) from exc
    return profile_from_toml(text, kind, source=label)


def load_roller_table() -> RollerTable:
    """Load ``rollers.toml``: the seven rollers of [000] with their provenance notes."""
    label = _label(_ROLLER_FILE)
    table = _read(_data_root() / _ROLLER_FILE, label, "roller_table")
    assert isinstance(table, RollerTable)
    return table


def load_rollers() -> dict[int, Roller]:
    """The seven rollers of [000], by number (1–7).

    Returns
    -------
    dict[int, Roller]
        A new dict on every call. Paper-unit fields as published; internal-unit properties
        ``k_s_n`` (fraction·N), ``k_inf_per_n`` (fraction/N), ``a_per_n``, ``b_per_n``
        (fraction/N), ``c_s_per_mm`` (s/mm), ``fp_min_eq9_n`` (N) and the
        ``max_feed_force_fit`` of Figs. 4–8.
    """
    return {r.number: r for r in load_roller_table().roller if r.number is not None}


def _profile_files() -> list[tuple[str, ProfileKind, Traversable]]:
    out: list[tuple[str, ProfileKind, Traversable]] = []
    root = _data_root()
    for folder, kind in _FOLDERS.items():
        directory = root / folder
        if not directory.is_dir():
            continue
        for item in sorted(directory.iterdir(), key=lambda t: t.name):
            if item.name.endswith(".toml") and item.is_file():
                out.append((item.name[:-5], kind, item))
    return out


def library_entries() -> list[LibraryEntry]:
    """Every built-in profile, in a stable order (by kind folder, then name).

    Raises
    ------
    ProfileError
        If a data file is invalid, its ``name`` differs from its file name, or two
        profiles share a name (a broken installation).
    """
    entries: list[LibraryEntry] = []
    for stem, kind, item in _profile_files():
        label = _label(f"{kind}s", item.name)
        profile = _read(item, label, kind)
        name = getattr(profile, "name", None)
        if name != stem:
            raise ProfileError("a built-in profile's name must equal its file name",
                               source=label, field="name", value=name, allowed=repr(stem))
        entries.append(LibraryEntry(stem, kind, getattr(profile, "description", ""), label))
    table = load_roller_table()
    entries.append(LibraryEntry(ROLLER_TABLE_NAME, "roller_table",
                                "The seven driving rollers of [000] (Tables 2-3, Figs. 4-8)",
                                _label(_ROLLER_FILE)))
    for roller in table.roller:
        entries.append(LibraryEntry(
            roller.name, "roller",
            f"{roller.label}, outer diameter {roller.outer_diameter_mm:g} mm "
            f"[000 Table 2, #{roller.number}]", _label(_ROLLER_FILE)))
    seen: dict[str, LibraryEntry] = {}
    for entry in entries:
        if entry.name in seen:
            raise ProfileError("two built-in profiles share a name", source=entry.resource,
                               field="name", value=entry.name,
                               allowed=f"a name not used by {seen[entry.name].resource}")
        seen[entry.name] = entry
    return entries


def library_names() -> list[str]:
    """Names of every built-in profile (see :func:`library_entries`)."""
    return [entry.name for entry in library_entries()]


def load_builtin(name: str, kind: ProfileKind | None = None) -> Profile:
    """Load a built-in profile by name.

    Parameters
    ----------
    name
        A name from :func:`library_names` (``"generic-klipper"``, ``"roller-3"``, ...).
    kind
        If given, the profile must be of this kind.

    Raises
    ------
    ProfileError
        Unknown name (with the closest names), or a profile of another kind.
    """
    # Fast path: open only the file the name points to.
    for stem, file_kind, item in _profile_files():
        if stem == name and (kind is None or kind == file_kind):
            return _read(item, _label(f"{file_kind}s", item.name), file_kind)
    if kind in (None, "roller_table") and name == ROLLER_TABLE_NAME:
        return load_roller_table()
    if kind in (None, "roller") and name.startswith("roller-"):
        for roller in load_roller_table().roller:
            if roller.name == name:
                return roller
    # Not found (or of another kind): build the full list for a helpful message.
    entries = {entry.name: entry for entry in library_entries()}
    entry = entries.get(name)
    if entry is None or (kind is not None and entry.kind != kind):
        candidates = [n for n, e in entries.items() if kind is None or e.kind == kind]
        close = difflib.get_close_matches(name, candidates, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        what = f"{kind} profile" if kind else "profile"
        reason = (f"unknown built-in {what}{hint}" if entry is None else
                  f"built-in profile {name!r} is a {entry.kind}, not a {kind}")
        raise ProfileError(reason, source="flowtwin/data", value=name,
                           allowed="one of " + ", ".join(candidates))
    raise AssertionError(f"built-in {name!r} listed but not loadable")  # pragma: no cover
