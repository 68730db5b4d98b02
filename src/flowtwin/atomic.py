"""Atomic output: a file is either complete or not there (no half-written outputs).

An operating-system error while the file is made (no space left, permission denied,
read-only folder, quota) becomes a :class:`~flowtwin.errors.FileAccessError` that names the
output path and the cause; the temporary file is removed and an existing file at ``path``
is untouched.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Literal, overload

from flowtwin.errors import file_access_error

__all__ = ["atomic_open", "atomic_write_bytes", "atomic_write_text"]


@overload
def atomic_open(path: str | os.PathLike[str], mode: Literal["w"] = ...,
                encoding: str | None = ...) -> contextlib.AbstractContextManager[IO[str]]: ...
@overload
def atomic_open(path: str | os.PathLike[str], mode: Literal["wb"],
                encoding: str | None = ...) -> contextlib.AbstractContextManager[IO[bytes]]: ...


def atomic_open(path: str | os.PathLike[str], mode: str = "w",
                encoding: str | None = "utf-8") -> contextlib.AbstractContextManager[IO]:  # type: ignore[type-arg]
    """Open ``path`` for writing through a temporary file in the same folder.

    On normal exit the temporary file is flushed, fsynced and renamed over ``path``
    (``os.replace`` is atomic on POSIX); on an exception it is deleted and ``path`` is
    left untouched. An ``OSError`` of the file system (:data:`WRITE_ERRNOS`) is raised as a
    :class:`~flowtwin.errors.FileAccessError` naming ``path``.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open mode must be 'w' or 'wb', got {mode!r}")
    return _atomic(Path(path), mode, None if mode == "wb" else encoding)


#: errno values that mean "this output cannot be written here" (the user's to fix)
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES,
                          errno.EPERM, errno.EFBIG, errno.EIO, errno.ENOTDIR,
                          errno.EISDIR, errno.ENAMETOOLONG, errno.EEXIST, errno.ENOENT})


@contextlib.contextmanager
def _atomic(path: Path, mode: str, encoding: str | None) -> Iterator[IO]:  # type: ignore[type-arg]
    try:
        with _atomic_file(path, mode, encoding) as fh:
            yield fh
    except OSError as exc:
        if exc.errno in WRITE_ERRNOS:
            raise file_access_error(exc, path, writing=True) from exc
        raise


@contextlib.contextmanager
def _atomic_file(path: Path, mode: str, encoding: str | None) -> Iterator[IO]:  # type: ignore[type-arg]
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    # mkstemp makes the file private (0600); give it the permissions a plain open() would
    os.fchmod(fd, 0o666 & ~_umask())
    try:
        with os.fdopen(fd, mode, encoding=encoding,
                       newline="" if encoding else None) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    """The process umask (read by setting and restoring it)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_open(path, "wb") as fh:
        fh.write(data)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_open(path, "w") as fh:
        fh.write(text)
