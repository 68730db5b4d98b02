"""API keys for printer hosts: from the environment or an owner-only file, never shown.

A key is wrapped in :class:`ApiKey`, whose ``str`` and ``repr`` are ``ApiKey(***)``, so it
cannot leak into a log line, a CSV row, an error message or a traceback's locals display by
accident; only :meth:`ApiKey.reveal` (called where the HTTP header is built) returns it.
There is deliberately no way to pass a key on the command line (it would show in ``ps`` and
the shell history).
"""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from pathlib import Path

from flowtwin.errors import ProfileError

__all__ = ["DEFAULT_KEY_ENV", "ApiKey", "load_api_key"]

#: Environment variable read when no other is named.
DEFAULT_KEY_ENV = "FLOWTWIN_API_KEY"


class ApiKey:
    """A secret API key; prints as ``ApiKey(***)``.

    Parameters
    ----------
    value
        The key (non-empty, no whitespace inside).
    origin
        Where it came from (``"env FLOWTWIN_API_KEY"``, a file path) for messages.
    """

    __slots__ = ("_value", "origin")

    def __init__(self, value: str, *, origin: str) -> None:
        if not value or any(c.isspace() for c in value):
            raise ProfileError("API key is empty or contains whitespace", source=origin,
                               allowed="one token without spaces")
        self._value = value
        self.origin = origin

    def reveal(self) -> str:
        """The key itself (only for building the request header)."""
        return self._value

    def __repr__(self) -> str:
        return "ApiKey(***)"

    __str__ = __repr__

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ApiKey) and other._value == self._value

    def __hash__(self) -> int:
        return hash(("ApiKey", self._value))

    def __reduce__(self) -> tuple[object, ...]:
        raise TypeError("ApiKey cannot be pickled")


def load_api_key(*, file: str | os.PathLike[str] | None = None, env: str | None = None,
                 environ: Mapping[str, str] | None = None) -> ApiKey | None:
    """Load an API key from a file (preferred when given) or an environment variable.

    Parameters
    ----------
    file
        Path of a file holding the key on its first line. It must be a regular file owned
        by the current user with no permissions for group or others (``chmod 600``).
    env
        Name of the environment variable to read when ``file`` is None
        (default :data:`DEFAULT_KEY_ENV`).
    environ
        Environment to read (default ``os.environ``).

    Returns
    -------
    ApiKey or None
        The key, or None when ``file`` is None and the variable is unset or empty.

    Raises
    ------
    ProfileError
        The file is missing, not a regular file, owned by someone else, readable or
        writable by group/others, or empty. The message never contains the key.
    """
    if file is not None:
        return _from_file(Path(file))
    name = env or DEFAULT_KEY_ENV
    value = (os.environ if environ is None else environ).get(name, "").strip()
    if not value:
        return None
    return ApiKey(value, origin=f"environment variable {name}")


def _from_file(path: Path) -> ApiKey:
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except FileNotFoundError:
        raise ProfileError("API key file not found", source=path) from None
    except OSError as exc:
        raise ProfileError(f"cannot open API key file ({exc.strerror})", source=path) from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise ProfileError("API key file is not a regular file", source=path)
    with os.fdopen(fd, "r", encoding="utf-8") as fh:
        if hasattr(os, "getuid") and st.st_uid != os.getuid():
            raise ProfileError("API key file belongs to another user", source=path,
                               value=f"uid {st.st_uid}", allowed=f"uid {os.getuid()}")
        mode = stat.S_IMODE(st.st_mode)
        if mode & 0o077:
            raise ProfileError("API key file is accessible by group or others", source=path,
                               value=oct(mode), allowed="owner-only permissions "
                               "(chmod 600 FILE)")
        first = fh.readline().strip()
    return ApiKey(first, origin=str(path))
