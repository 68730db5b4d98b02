"""Where the CLI's Ctrl-C / SIGTERM handler must not raise (``cli.main._unsafe_to_raise``):
inside a lock's Python callbacks (llvmlite's lock around every LLVM call, numba's events and
compiler lock), a ctypes callback or a finalizer. Raised there, the exception would leave
the lock held by the main thread (a write-ahead worker loading a kernel then waits for ever,
and so does the exit that joins it) or be dropped (the run would go on). The handler sends
the signal again to the main thread instead."""

from __future__ import annotations

import os
import sys
from types import FrameType

import pytest

from flowtwin.cli.main import _unsafe_to_raise


def _frame_in(filename: str, name: str = "f") -> FrameType:
    """A real frame of a function ``name`` defined in a file named ``filename``."""
    space: dict[str, object] = {"sys": sys}
    exec(compile(f"def {name}():\n    return sys._getframe()\n", filename, "exec"), space)
    frame = space[name]()  # type: ignore[operator]
    assert isinstance(frame, FrameType)
    return frame


@pytest.mark.parametrize("filename", [
    os.path.join("site-packages", "llvmlite", "binding", "ffi.py"),
    os.path.join("site-packages", "numba", "core", "compiler_lock.py"),
    os.path.join("site-packages", "numba", "core", "event.py"),
])
def test_inside_a_locks_python_callbacks_the_signal_waits(filename: str) -> None:
    assert _unsafe_to_raise(_frame_in(filename, "__enter__"))


def test_inside_a_ctypes_callback_or_a_finalizer_the_signal_waits() -> None:
    assert _unsafe_to_raise(_frame_in(os.path.join("llvmlite", "binding",
                                                   "executionengine.py"),
                                      "_raw_object_cache_getbuffer"))
    assert _unsafe_to_raise(_frame_in("anything.py", "__del__"))


def test_elsewhere_the_signal_is_raised_at_once() -> None:
    assert not _unsafe_to_raise(sys._getframe())
    assert not _unsafe_to_raise(_frame_in(os.path.join("numba", "core", "dispatcher.py")))
    assert not _unsafe_to_raise(_frame_in(os.path.join("llvmlite", "binding",
                                                       "executionengine.py"), "add_module"))
    assert not _unsafe_to_raise(None)
