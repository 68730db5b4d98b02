"""Atomic output: a file is either complete or not there (no half-written outputs).

The file is written unnamed (Linux ``O_TMPFILE``) in the target's folder, fsynced, given a
temporary name and renamed over the target: a process killed at any moment leaves the old
file (or none) and no partial file. Where unnamed files are not available a named hidden
temporary carrying the writer's pid is used; one left by a killed writer is removed by the
next write to the same path (:func:`remove_stale_temporaries`).

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

__all__ = ["atomic_open", "atomic_write_bytes", "atomic_write_text", "remove_stale_temporaries"]


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
    remove_stale_temporaries(path)
    fd = _unnamed_file(path.parent)
    named = fd is None
    if fd is None:  # no O_TMPFILE here: a named temporary (its name carries our pid)
        fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path), suffix=".tmp", dir=path.parent)
        # mkstemp makes the file private (0600); give it the permissions open() would
        os.fchmod(fd, 0o666 & ~_umask())
    else:
        tmp = ""
    try:
        with os.fdopen(fd, mode, encoding=encoding,
                       newline="" if encoding else None) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
            if not named:  # give the unnamed file a name only now, complete
                tmp = os.path.join(path.parent, f"{_temp_prefix(path)}{os.urandom(4).hex()}.tmp")
                _name_unnamed(fh.fileno(), path.parent, os.path.basename(tmp))
        os.replace(tmp, path)
    except BaseException:
        if tmp:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        raise


def _name_unnamed(fd: int, folder: Path, name: str) -> None:
    """Link an ``O_TMPFILE`` file into ``folder``: ``linkat`` of its /proc descriptor,
    following the link (a directory descriptor makes Python use ``linkat`` with
    ``AT_SYMLINK_FOLLOW``; plain ``link`` would link the /proc symlink itself)."""
    dir_fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.link(f"/proc/self/fd/{fd}", name, dst_dir_fd=dir_fd, follow_symlinks=True)
    finally:
        os.close(dir_fd)


def _temp_prefix(path: Path) -> str:
    return f".{path.name}.{os.getpid()}."


def _unnamed_file(folder: Path) -> int | None:
    """An unnamed file in ``folder`` (Linux ``O_TMPFILE``): a process killed while writing
    it leaves nothing behind. None where the system or file system has none."""
    flag = getattr(os, "O_TMPFILE", None)
    if flag is None or not os.path.isdir("/proc/self/fd"):
        return None
    try:
        return os.open(folder, flag | os.O_WRONLY, 0o666)
    except OSError as exc:
        if exc.errno in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL):
            return None
        raise


def remove_stale_temporaries(path: str | os.PathLike[str]) -> list[Path]:
    """Delete the temporaries of ``path`` left by writers that no longer run.

    A writer killed with no chance to clean up (``SIGKILL``, power loss) can leave a
    hidden ``.NAME.PID.XXXX.tmp`` beside ``NAME`` (only with the named fallback, or in the
    instant between naming the complete file and renaming it). Those whose process is gone
    are removed; a live writer's are kept.

    Returns
    -------
    list of Path
        The files removed.
    """
    target = Path(path)
    removed = []
    for tmp in target.parent.glob(f".{glob_escape(target.name)}.*.tmp"):
        pid_text = tmp.name[len(target.name) + 2:].split(".", 1)[0]
        if not pid_text.isdigit() or _alive(int(pid_text)):
            continue
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
            removed.append(tmp)
    return removed


def glob_escape(name: str) -> str:
    """``name`` with the glob metacharacters escaped."""
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


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
