"""Error types of flowtwin.

Every error a user can cause (bad G-code, profile, CSV, image, video, connection) is a
:class:`FlowtwinError`. Its message names *where* (file, line or field), *what* (the value)
and *what is allowed*, so the CLI can print it and exit non-zero without a traceback.
"""

from __future__ import annotations

from os import PathLike

__all__ = [
    "CalibrationError",
    "DataError",
    "FileAccessError",
    "FlowtwinError",
    "GcodeError",
    "PrinterConnectionError",
    "ProfileError",
    "VisionError",
    "file_access_error",
    "format_location",
]


def format_location(source: str | PathLike[str] | None, line: int | None = None,
                    field: str | None = None) -> str:
    """Return ``file:line`` / ``file [field]`` style location text (empty parts omitted)."""
    parts = str(source) if source is not None else "<input>"
    if line is not None:
        parts += f":{line}"
    if field:
        parts += f" [{field}]"
    return parts


class FlowtwinError(ValueError):
    """Base class of every error flowtwin reports to a user.

    Parameters
    ----------
    message
        What is wrong, in words.
    source
        File name (or ``"<stdin>"``) the bad input came from, if any.
    line
        1-based line number in ``source``, if any.
    field
        Key, column or option name, if any.
    value
        The offending value, if any (shown with ``repr``, truncated to 80 characters).
    allowed
        What would have been accepted (e.g. ``"0 < x <= 500"``).
    """

    def __init__(self, message: str, *, source: str | PathLike[str] | None = None,
                 line: int | None = None, field: str | None = None,
                 value: object = None, allowed: str | None = None) -> None:
        self.message = message
        self.source = None if source is None else str(source)
        self.line = line
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(self._render())

    def _render(self) -> str:
        text = ""
        if self.source is not None or self.line is not None or self.field:
            text = format_location(self.source, self.line, self.field) + ": "
        text += self.message
        if self.value is not None:
            shown = repr(self.value)
            if len(shown) > 80:
                shown = shown[:77] + "..."
            text += f"; got {shown}"
        if self.allowed:
            text += f"; allowed: {self.allowed}"
        return text


class GcodeError(FlowtwinError):
    """Malformed or unsupported G-code (names file and line)."""


class ProfileError(FlowtwinError):
    """Invalid profile or printer configuration (names file, key, value, allowed range)."""


class DataError(FlowtwinError):
    """Malformed measurement data: CSV, Parquet, test-stand records."""


class VisionError(FlowtwinError):
    """Unreadable video or image, ROI outside the frame, unusable calibration."""


class CalibrationError(FlowtwinError):
    """A fit that cannot be made from the data given (carries the reason)."""


class PrinterConnectionError(FlowtwinError):
    """A printer host could not be reached or answered with an error."""


class FileAccessError(FlowtwinError):
    """A file could not be read or written: the path and the system's reason (no space
    left, permission denied, read-only file system, not found, ...)."""


def file_access_error(exc: OSError, path: str | PathLike[str] | None = None, *,
                      writing: bool | None) -> FileAccessError:
    """The :class:`FileAccessError` for an operating-system error on ``path``.

    Parameters
    ----------
    exc
        The ``OSError`` (its ``strerror`` and ``errno`` name the cause).
    path
        The file the user named (default: the error's own ``filename``).
    writing
        Whether the file was being written (the message says the old file, if any, is
        unchanged: outputs are written atomically), read (False) or either (None).
    """
    import errno as _errno

    where = path if path is not None else exc.filename
    reason = exc.strerror or type(exc).__name__
    code = _errno.errorcode.get(exc.errno or -1)
    if code:
        reason += f" ({code})"
    if writing:
        return FileAccessError(f"cannot write the file: {reason}; nothing was written "
                               "(an existing file there is unchanged)", source=where)
    if writing is None:
        return FileAccessError(f"cannot open the file: {reason}", source=where)
    return FileAccessError(f"cannot read the file: {reason}", source=where)
