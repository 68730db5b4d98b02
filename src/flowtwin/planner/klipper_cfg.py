"""Klipper ``printer.cfg`` text: sections, options, includes, SAVE_CONFIG, typed values.

:func:`read_cfg` parses a real ``printer.cfg`` the way Klipper's ``configfile.py`` does:
sections and ``option: value`` / ``option = value`` lines, indented continuation lines
(macro bodies), ``#`` / ``;`` comments, ``[include ...]`` files (relative paths and
globs) and the ``#*#`` SAVE_CONFIG block, whose values override. :class:`Section` reads
options with Klipper's ``getfloat`` / ``getint`` / ``getlists`` rules;
every error is a :class:`~flowtwin.errors.ProfileError` naming the file, line,
``[section] option``, the value and what is allowed.
"""

from __future__ import annotations

import glob
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from flowtwin.errors import ProfileError

__all__ = ["CfgFile", "CfgOption", "Section", "check_value", "read_cfg"]


def check_value(source: str, option: str, value: float, *, minval: float | None = None,
           maxval: float | None = None, above: float | None = None,
           below: float | None = None, line: int | None = None,
           section: str | None = None) -> float:
    """Klipper's ``getfloat`` bounds; raise :class:`ProfileError` naming the option."""
    where = f"[{section}] {option}" if section else option
    ok = isinstance(value, int | float) and math.isfinite(value)
    parts = []
    if minval is not None:
        parts.append(f">= {minval:g}")
        ok = ok and value >= minval
    if above is not None:
        parts.append(f"> {above:g}")
        ok = ok and value > above
    if maxval is not None:
        parts.append(f"<= {maxval:g}")
        ok = ok and value <= maxval
    if below is not None:
        parts.append(f"< {below:g}")
        ok = ok and value < below
    if not ok:
        raise ProfileError(f"option '{option}' out of range", source=source, line=line,
                           field=where, value=value,
                           allowed=" and ".join(parts) or "a finite number")
    return float(value)




@dataclass(slots=True)
class CfgOption:
    """One option's raw value and where it was written."""

    value: str
    source: str
    line: int


@dataclass(slots=True)
class CfgFile:
    """Sections of a printer.cfg (after includes and SAVE_CONFIG): options with their
    file and line, and where each section header is."""

    source: str = "<printer.cfg>"
    sections: dict[str, dict[str, CfgOption]] = field(default_factory=dict)
    headers: dict[str, tuple[str, int]] = field(default_factory=dict)

    def has_section(self, name: str) -> bool:
        """The file (or an include) has section ``[name]``."""
        return name in self.sections

    def section(self, name: str) -> Section:
        """Typed view of ``[name]`` (empty if absent: every option takes its default)."""
        return Section(self, name)

    def require(self, name: str, allowed: str) -> Section:
        """``[name]``, or a :class:`ProfileError` saying it is missing."""
        if name not in self.sections:
            raise ProfileError(f"no [{name}] section", source=self.source, field=name,
                               allowed=allowed)
        return Section(self, name)

    def prefix_sections(self, prefix: str) -> Iterator[Section]:
        """Sections whose name starts with ``prefix`` (``"carriage "``), in file order."""
        for name in self.sections:
            if name.startswith(prefix):
                yield Section(self, name)


AUTOSAVE_MARK = "#*#"
MAX_INCLUDE_DEPTH = 20


def _strip_comment(text: str) -> str:
    """Drop a ``#``/``;`` comment (full line, or inline after whitespace) like configparser."""
    stripped = text.strip()
    if not stripped or stripped[0] in "#;":
        return ""
    for i, ch in enumerate(text):
        if ch in "#;" and i > 0 and text[i - 1].isspace():
            return text[:i].rstrip()
    return text.rstrip()


def _parse_text(text: str, source: str, cfg: CfgFile, depth: int) -> None:
    """Add the sections of one file (and its includes) to ``cfg``; later values win."""
    section: str | None = None
    last: CfgOption | None = None
    lines = text.split("\n")
    autosave: list[tuple[int, str]] = []
    for number, raw in enumerate(lines, start=1):
        raw = raw.rstrip("\r")
        if raw.startswith(AUTOSAVE_MARK):
            autosave.append((number, raw[len(AUTOSAVE_MARK):].lstrip(" ")
                             if raw[len(AUTOSAVE_MARK):].startswith(" ")
                             else raw[len(AUTOSAVE_MARK):]))
            continue
        body = _strip_comment(raw)
        if not body:
            continue
        if raw[0].isspace():
            if last is None:
                raise ProfileError("indented line outside an option", source=source,
                                   line=number, value=raw.strip(),
                                   allowed="'option: value' inside a [section]")
            continue  # continuation of a multi-line value (macro body): not needed here
        if body.startswith("["):
            if not body.endswith("]"):
                raise ProfileError("malformed section header", source=source, line=number,
                                   value=body, allowed="[section name]")
            name = body[1:-1].strip()
            if name.startswith("include ") or name == "include":
                _include(name[len("include"):].strip(), source, number, cfg, depth)
                section, last = None, None
                continue
            section = name
            cfg.sections.setdefault(name, {})
            cfg.headers.setdefault(name, (source, number))
            last = None
            continue
        cut = min((i for i in (body.find(":"), body.find("=")) if i >= 0), default=-1)
        if cut <= 0:
            raise ProfileError("cannot parse line", source=source, line=number, value=body,
                               allowed="'[section]', 'option: value' or 'option = value'")
        if section is None:
            raise ProfileError("option before the first [section]", source=source,
                               line=number, value=body, allowed="options inside a [section]")
        key = body[:cut].strip().lower()
        last = CfgOption(body[cut + 1:].strip(), source, number)
        cfg.sections[section][key] = last
    if autosave:
        _parse_autosave(autosave, source, cfg)


def _parse_autosave(lines: list[tuple[int, str]], source: str, cfg: CfgFile) -> None:
    """The SAVE_CONFIG block at the end of printer.cfg (``#*# [section]`` ...) overrides."""
    section: str | None = None
    for number, text in lines:
        body = _strip_comment(text)
        if not body or text[:1].isspace():
            continue
        if section is None and not body.startswith("["):
            continue  # the block's header lines ("<--- SAVE_CONFIG --->", "DO NOT EDIT ...")
        if body.startswith("[") and body.endswith("]"):
            section = body[1:-1].strip()
            cfg.sections.setdefault(section, {})
            cfg.headers.setdefault(section, (source, number))
            continue
        cut = min((i for i in (body.find(":"), body.find("=")) if i >= 0), default=-1)
        if cut <= 0 or section is None:
            raise ProfileError("cannot parse SAVE_CONFIG line", source=source, line=number,
                               value=body, allowed="'#*# option = value' after '#*# [section]'")
        cfg.sections[section][body[:cut].strip().lower()] = CfgOption(body[cut + 1:].strip(),
                                                                 source, number)


def _include(pattern: str, source: str, line: int, cfg: CfgFile, depth: int) -> None:
    """Klipper ``[include file]``: relative to the including file, globs allowed."""
    if not pattern:
        raise ProfileError("include without a file name", source=source, line=line,
                           allowed="[include other.cfg]")
    if depth >= MAX_INCLUDE_DEPTH:
        raise ProfileError("includes nested too deeply (recursive include?)", source=source,
                           line=line, value=pattern, allowed=f"<= {MAX_INCLUDE_DEPTH} levels")
    base = Path(source).parent
    full = os.path.join(base, pattern)
    names = sorted(glob.glob(full))
    if not names and not glob.has_magic(full):
        raise ProfileError("included file does not exist", source=source, line=line,
                           value=pattern, allowed="an existing file (path relative to "
                           "the including file)")
    for name in names:
        _parse_text(_read_text(name), name, cfg, depth + 1)


def _read_text(path: str | os.PathLike[str]) -> str:
    try:
        return Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ProfileError(f"cannot read printer.cfg: {exc.strerror}", source=str(path)) from exc
    except UnicodeDecodeError as exc:
        raise ProfileError("printer.cfg is not UTF-8 text", source=str(path)) from exc


class Section:
    """Typed access to one section's options with Klipper's bounds.

    Parameters
    ----------
    cfg
        The parsed file.
    name
        Section name (``"printer"``, ``"stepper_a"``, ``"carriage x"``).
    """

    def __init__(self, cfg: CfgFile, name: str) -> None:
        self.cfg = cfg
        self.name = name
        self.opts = cfg.sections.get(name, {})
        self.source, self.line = cfg.headers.get(name, (cfg.source, 0))

    def has(self, option: str) -> bool:
        """The option is written in this section."""
        return option in self.opts

    def where(self, option: str) -> tuple[str, int | None]:
        """File and line of an option (of the section header if it is absent)."""
        opt = self.opts.get(option)
        if opt is not None:
            return opt.source, opt.line
        return self.source, self.line or None

    def error(self, option: str, message: str, *, value: object = None,
              allowed: str | None = None) -> ProfileError:
        """A :class:`ProfileError` located at ``option`` (or the section header)."""
        source, line = self.where(option)
        return ProfileError(message, source=source, line=line,
                            field=f"[{self.name}] {option}", value=value, allowed=allowed)

    def _missing(self, option: str, allowed: str) -> ProfileError:
        return ProfileError(f"option '{option}' is required in section [{self.name}]",
                            source=self.source, line=self.line or None,
                            field=f"[{self.name}] {option}", allowed=allowed)

    def get(self, option: str, default: str | None = None) -> str:
        """Raw text of an option; ``default`` when absent (required if ``None``)."""
        opt = self.opts.get(option)
        if opt is None:
            if default is None:
                raise self._missing(option, "a value")
            return default
        return opt.value

    def getfloat(self, option: str, default: float | None = None, *,
                 minval: float | None = None, maxval: float | None = None,
                 above: float | None = None, below: float | None = None) -> float:
        """A number with Klipper's bounds; ``default`` when absent (required if ``None``).

        As in Klipper, the bounds are checked on written values only.
        """
        opt = self.opts.get(option)
        if opt is None:
            if default is None:
                raise self._missing(option, "a number")
            return default
        try:
            value = float(opt.value)
            if not math.isfinite(value):
                raise ValueError(opt.value)
        except ValueError:
            raise ProfileError(f"unable to parse option '{option}'", source=opt.source,
                               line=opt.line, field=f"[{self.name}] {option}",
                               value=opt.value, allowed="a finite decimal number") from None
        return check_value(opt.source, option, value, minval=minval, maxval=maxval,
                           above=above, below=below, line=opt.line, section=self.name)

    def getint(self, option: str, default: int | None = None, *,
               minval: int | None = None, maxval: int | None = None) -> int:
        """An integer with Klipper's bounds; ``default`` when absent (required if ``None``)."""
        opt = self.opts.get(option)
        if opt is None:
            if default is None:
                raise self._missing(option, "an integer")
            return default
        try:
            value = int(opt.value)
        except ValueError:
            raise ProfileError(f"unable to parse option '{option}'", source=opt.source,
                               line=opt.line, field=f"[{self.name}] {option}",
                               value=opt.value, allowed="an integer") from None
        check_value(opt.source, option, value, minval=minval, maxval=maxval,
                    line=opt.line, section=self.name)
        return value

    def getpairs(self, option: str) -> list[tuple[float, float]]:
        """Klipper ``getlists(seps=(':', ','), count=2)``: ``"80:16, 3:1"`` → pairs."""
        opt = self.opts.get(option)
        if opt is None or not opt.value.strip():
            return []
        pairs = []
        for part in opt.value.split(","):
            items = part.split(":")
            try:
                if len(items) != 2:
                    raise ValueError
                pairs.append((float(items[0]), float(items[1])))
            except ValueError:
                raise ProfileError(f"unable to parse option '{option}'", source=opt.source,
                                   line=opt.line, field=f"[{self.name}] {option}",
                                   value=opt.value,
                                   allowed="comma-separated ratios 'a:b'") from None
        return pairs


def read_cfg(path: str | os.PathLike[str]) -> CfgFile:
    """Parse a ``printer.cfg`` (and its includes).

    Raises
    ------
    ProfileError
        The file cannot be read or parsed (names file and line).
    """
    cfg = CfgFile(source=str(path))
    _parse_text(_read_text(path), str(path), cfg, 0)
    return cfg
