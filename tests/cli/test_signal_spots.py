"""Where the CLI's Ctrl-C / SIGTERM handler must not raise (``cli.main._unsafe_to_raise``):
inside a lock's Python callbacks (llvmlite's lock around every LLVM call, numba's events and
compiler lock), Python code that C code calls back into (numba's unpickler of a cached
kernel's constants, the import machinery), a ctypes callback or a finalizer. Raised there,
the exception would leave the lock held by the main thread (a write-ahead worker loading a
kernel then waits for ever, and so does the exit that joins it), be dropped (the run would
go on), or come out as another error or a crash. The handler sends the signal again to the
main thread instead."""

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


@pytest.mark.parametrize("filename", [
    # numba's unpickler of a cached kernel's constants, called by the dispatcher's C code
    # on the kernel's first call: a KeyboardInterrupt raised there gave a SystemError
    # ("returned a result with an exception set") or a SIGSEGV (tests/cli/test_interrupts)
    os.path.join("site-packages", "numba", "core", "serialize.py"),
    # the import machinery: an extension module's init turned it into an ImportError
    "<frozen importlib._bootstrap>",
    "<frozen importlib._bootstrap_external>",
])
def test_inside_code_that_c_calls_back_the_signal_waits(filename: str) -> None:
    assert _unsafe_to_raise(_frame_in(filename, "_numba_unpickle"))


def test_the_real_import_machinery_and_unpickler_are_such_places() -> None:
    # the file names these functions run under on this Python and numba
    import importlib._bootstrap as bootstrap
    import importlib._bootstrap_external as external

    import numba.core.serialize as serialize

    for fn in (bootstrap._find_and_load, external.SourceFileLoader.exec_module,
               serialize._numba_unpickle):
        assert _unsafe_to_raise(_frame_in(fn.__code__.co_filename, fn.__name__))


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
