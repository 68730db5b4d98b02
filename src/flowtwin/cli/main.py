"""Entry point of the ``flowtwin`` command.

Each command group lives in its own module with a ``register(app)`` function. This module
lists them in :data:`COMMANDS` (name, module, help line) and loads a module only when its
command runs or shows its own help, so ``flowtwin --help`` and ``flowtwin plan ...`` import
what they use and nothing else (no OpenCV, dask, matplotlib, ... for a plan). It turns
:class:`~flowtwin.errors.FlowtwinError` into a one-line message on stderr and a non-zero
exit status (never a traceback to a user).
"""

from __future__ import annotations

import atexit
import gc
import os
import signal
import sys
import threading
from types import FrameType
from typing import TYPE_CHECKING, Annotated, Any, NoReturn, Protocol, cast

import typer

from flowtwin import __version__
from flowtwin.cli.lazy_group import lazy_group
from flowtwin.errors import FlowtwinError, file_access_error

if TYPE_CHECKING:
    from rich.console import Console

__all__ = ["COMMANDS", "app", "build_app", "exit_process", "main", "run"]

#: Every command of ``flowtwin``: name -> (module under ``flowtwin.cli`` whose
#: ``register(app)`` adds it, the line ``flowtwin --help`` shows for it). A module is imported
#: only when one of its commands is run (or asked for its help); ``tests/cli`` checks that
#: each line is the first paragraph of the command's own help.
COMMANDS: dict[str, tuple[str, str]] = {
    "plan": ("plan", "Plan a G-code file as Klipper or Marlin would: time, filament, moves, "
             "layers."),
    "simulate": ("simulate", "Predict what a G-code really extrudes: flow, bead width, slip, "
                 "force, grinding."),
    "compensate": ("compensate", "Rewrite a G-code so the printer extrudes what it means "
                   "(nothing without a flag)."),
    "tune": ("compensate", "The firmware's pressure advance that best fits the machine, and "
             "why."),
    "demo": ("demo", "Generate the built-in example print, plan and simulate it, write "
             "report.html."),
    "batch": ("batch", "Simulate many G-code files on one machine: one table row per file."),
    "sweep": ("batch", "Simulate one G-code over a grid (or random sample) of profile "
              "parameters."),
    "reproduce": ("reproduce", "Reproduce the quantitative claims of a seed paper (or all): "
                  "table, figures, JSON."),
    "control": ("control", "Run the slip control loop: measure, command M220/M221, restore "
                "100 % at the end."),
    "limits": ("limits", "Maximum volumetric flow (mm³/s) of a set-up, why, and against "
               "temperature."),
    "profiles": ("profiles", "Built-in and user profiles (printer, drive, hot end, material, "
                 "filament, set-up)."),
    "calibrate": ("calibrate", "Calibration: test patterns, fits of measurements, profile "
                  "fragments, adaptive pressure-advance tables."),
    "teststand": ("teststand", "Virtual filament-drive test stand [000 §3] and evaluation of "
                  "test-stand records."),
    "vision": ("vision", "Measure filament speed, gear speed, slip and width from a camera "
               "[003]."),
    "postprocess": ("postprocess", "Write firmware-exact times into a sliced G-code and check "
                    "it with the twin."),
}

#: The command modules, each once, in the order of :data:`COMMANDS`.
COMMAND_MODULES = tuple(dict.fromkeys(module for module, _ in COMMANDS.values()))

EXIT_USER_ERROR = 2
EXIT_INTERNAL_ERROR = 3


#: The group class of ``flowtwin``: every command of :data:`COMMANDS`, loaded when used.
LazyGroup = lazy_group("flowtwin", COMMANDS)


def _show_version(value: bool) -> None:
    if value:
        print(f"flowtwin {__version__}")
        raise typer.Exit()


def _root(
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.",
                                          callback=_show_version, is_eager=True)] = False,
) -> None:
    """Digital twin of the extrusion system of a filament 3D printer."""


def build_app() -> typer.Typer:
    """The typer application: every command of :data:`COMMANDS`, loaded when used."""
    application = typer.Typer(
        name="flowtwin",
        help="Digital twin of the extrusion system of a filament 3D printer.",
        cls=LazyGroup,
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
    )
    application.callback()(_root)
    return application


app = build_app()


class _ClickError(Protocol):
    """What a click exception offers: its message printer and its exit status."""

    exit_code: int

    def show(self) -> None: ...


#: Where click's exceptions live: click itself, or the copy typer >= 0.23 vendors.
_CLICK_MODULES = ("click.exceptions", "typer._click.exceptions", "typer.exceptions")


def _click_kind(exc: BaseException) -> str | None:
    """``"ClickException"`` (usage errors and the like) or ``"Abort"`` when ``exc`` is one of
    click's, whichever copy of click raised it; else ``None``."""
    for cls in type(exc).__mro__:
        if cls.__module__ in _CLICK_MODULES and cls.__name__ in ("ClickException", "Abort"):
            return cls.__name__
    return None


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; user errors exit 2 with a message, internal errors exit 3; Ctrl-C exits
    130 and ``SIGTERM`` 143, leaving no partial output (atomic writes unwind)."""
    terminated: list[int] = []
    # signals put off (below) and not taken yet; the timers that send them again; and
    # whether the command is over (from then on a signal is only recorded, and the exit
    # path decides: it never raises in the middle of the error message or the exit)
    deferred: list[int] = []
    timers: list[threading.Timer] = []
    over: list[bool] = []

    def settle() -> None:
        """The command is over: no put-off signal is sent again."""
        over.append(True)
        for timer in timers:
            timer.cancel()

    def command() -> Any:
        """The command itself; once it returns or raises, it is over (:func:`settle`),
        before any message is printed or exit taken."""
        try:
            # standalone_mode=False returns typer.Exit codes instead of exiting with them
            return app(args=argv, standalone_mode=False)
        finally:
            settle()

    def interrupt(signum: int, frame: FrameType | None) -> None:
        if over:
            deferred.append(signum)
            return
        if _unsafe_to_raise(frame):
            # raised there, the exception would be dropped (a ctypes callback, a
            # finalizer) or would leave a lock held for good (between a lock's acquire and
            # its ``with`` body): another thread needing it would then hang, and so would
            # the exit that waits for that thread. Take the signal again once out of there.
            deferred.append(signum)
            timers[:] = [timer for timer in timers if timer.is_alive()]
            timers.append(_resend_soon(signum))
            return
        deferred.clear()
        for timer in timers:  # taken now: what was put off is not sent again
            timer.cancel()
        if signum == signal.SIGTERM:  # unwind like Ctrl-C: outputs are dropped whole
            terminated.append(signum)
        raise KeyboardInterrupt

    previous: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, interrupt)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            # Python's Ctrl-C, callback-safe
            previous[signal.SIGINT] = signal.signal(signal.SIGINT, interrupt)
    try:
        try:
            code = command()
        except FlowtwinError as exc:
            _err().print(f"[bold red]error:[/] {_escape(str(exc))}", markup=True, soft_wrap=True)
            sys.exit(EXIT_USER_ERROR)
        except OSError as exc:
            if exc.filename is None:  # not about a file the user named: a bug, below
                _internal_error(exc)
            message = _escape(str(file_access_error(exc, writing=None)))
            _err().print(f"[bold red]error:[/] {message}", markup=True, soft_wrap=True)
            sys.exit(EXIT_USER_ERROR)
        except KeyboardInterrupt:
            _interrupted(terminated)
        except SystemExit:
            raise
        except Exception as exc:  # last line of defence for the user
            kind = _click_kind(exc)
            if kind == "ClickException":  # a usage error: typer's message, exit 2
                usage = cast(_ClickError, exc)
                usage.show()
                sys.exit(usage.exit_code)
            if kind == "Abort":  # click's Ctrl-C (or SIGTERM, through the handler)
                _interrupted(terminated)
            _internal_error(exc)
        else:
            if code == 130:  # typer's answer to a KeyboardInterrupt (Ctrl-C, our SIGTERM)
                _interrupted(terminated)
            if deferred:
                # a signal put off near the end was not sent again before the command
                # ended: it is taken now (the outputs are complete, the exit says so). A
                # command that failed keeps its error's exit status instead.
                terminated.extend(sig for sig in deferred if sig == signal.SIGTERM)
                _interrupted(terminated)
            sys.exit(code if isinstance(code, int) else 0)
    finally:
        # the command is over, its outputs written or dropped whole: a signal from now on
        # would only interrupt the exit (its handlers, the wait for a writer thread), where
        # the exception is printed and dropped; the process's own handling takes it
        for signum, handler in previous.items():
            signal.signal(signum, handler)


#: Seconds from the start of a ``flowtwin`` process without automatic garbage collection.
GC_PAUSE_S = 1.0


def run() -> NoReturn:
    """The ``flowtwin`` process: :func:`main`, with the garbage collector kept off the
    start-up and the exit, and an exit without the interpreter's teardown.

    A command's first second imports numpy, numba, pydantic and flowtwin and loads its
    kernels: ~100 k objects that live as long as the process. CPython's collector would
    traverse all of them in each full collection it starts meanwhile (0.05-0.12 s on a
    Benchy post-process), and again in the collections of the interpreter's exit
    (0.15-0.2 s). So automatic collection is off for :data:`GC_PAUSE_S`, after which
    everything then alive is frozen (:func:`gc.freeze`: left to reference counting, never
    traversed again) and collection resumes for the rest of a long command; at exit the
    same freeze skips the teardown's passes. Reference counting, ``__del__`` and the exit
    handlers run as always, and a process forked meanwhile collects from its start. Only
    the process entry points call this, never :func:`main` run inside another program (a
    test), whose garbage must stay collectable. The exit is :func:`exit_process`'s.
    Measured in docs/performance.md.
    """
    gc.disable()
    resume = threading.Timer(GC_PAUSE_S, _resume_collection)
    resume.daemon = True
    resume.start()
    os.register_at_fork(after_in_child=gc.enable)
    code: object = 0
    try:
        main()
    except SystemExit as exc:
        code = exc.code
    finally:
        resume.cancel()
        gc.freeze()
    exit_process(code)


def exit_process(code: object) -> NoReturn:
    """End the process with ``code`` (as :class:`SystemExit` would) without the
    interpreter's teardown.

    Python's own exit, once the exit handlers have run, takes every module apart and
    frees its objects one by one, numba's and LLVM's included: 0.02 s of a 0.5 s command,
    with nothing to show for it since the process ends. So, when no other (non-daemon)
    thread is left to wait for, the exit handlers (:mod:`atexit`: logging's flush,
    temporary directories' clean-up, ...) are run and the standard streams flushed here,
    then the process ends at once (:func:`os._exit`). Files the program wrote are closed
    by then (every output is written atomically, in a ``with``). Otherwise the
    interpreter exits as usual.
    """
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:  # SystemExit("message"): printed, status 1
        print(code, file=sys.stderr)
        status = 1
    if any(t.is_alive() and not t.daemon and t is not threading.main_thread()
           for t in threading.enumerate()):
        sys.exit(status)  # the interpreter joins them first
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (OSError, ValueError):  # a closed pipe: as Python's own exit does
            status = status or 120
    os._exit(status)


def _resume_collection() -> None:
    """End of the start-up: freeze what is alive, collect what comes after."""
    gc.freeze()
    gc.enable()


#: Python functions that C code calls back and whose exception it prints and drops, so the
#: run would go on: (file name ending, function name). llvmlite's object cache, called
#: through ctypes while numba compiles or loads a kernel; and weak-reference callbacks,
#: which the garbage collector runs wherever it happens to collect (numba's type cache,
#: the weak containers of ``weakref`` and ``_weakrefset``, ``weakref.finalize``).
_NATIVE_CALLBACKS = (("executionengine.py", "_raw_object_cache_notify"),
                     ("executionengine.py", "_raw_object_cache_getbuffer"),
                     ("numba/core/types/abstract.py", "_on_type_disposal"),
                     ("/weakref.py", "remove"), ("/weakref.py", "__call__"),
                     ("/_weakrefset.py", "_remove"))
#: Modules whose locks run Python code between the lock's acquire and the ``with`` body
#: (and before its release): llvmlite's lock around every LLVM call, whose callbacks are
#: numba's events, and numba's compiler lock. An exception raised there leaves the lock
#: held by the main thread, and a worker thread that loads a kernel then waits for ever.
_LOCK_MODULES = ("llvmlite/binding/ffi.py", "numba/core/compiler_lock.py",
                 "numba/core/event.py")
#: Python code that C code calls back into and whose exception it does not pass on: numba's
#: unpickler of a cached kernel's constants, run by the dispatcher on a kernel's first call
#: (an exception raised there made the call return a result with an exception set, a
#: ``SystemError``, or crashed the process with SIGSEGV), and the import machinery (an
#: extension module's initialisation turns it into an ``ImportError``).
_CALLBACK_MODULES = ("numba/core/serialize.py", "<frozen importlib._bootstrap>",
                     "<frozen importlib._bootstrap_external>")


def _unsafe_to_raise(frame: FrameType | None) -> bool:
    """Whether ``frame`` runs where an exception must not be raised: inside one of
    :data:`_NATIVE_CALLBACKS`, one of :data:`_LOCK_MODULES` or :data:`_CALLBACK_MODULES`,
    or a finalizer (``__del__``: Python drops what it raises)."""
    while frame is not None:
        code = frame.f_code
        name, file = code.co_name, code.co_filename.replace(os.sep, "/")
        if name == "__del__" or file.endswith(_LOCK_MODULES + _CALLBACK_MODULES) or any(
                name == cb and file.endswith(f) for f, cb in _NATIVE_CALLBACKS):
            return True
        frame = frame.f_back
    return False


def _resend_soon(signum: int) -> threading.Timer:
    """Send ``signum`` to the main thread again in 10 ms (from a daemon thread): to the
    main thread itself, so that a wait it is in (for a worker, say) is interrupted.
    Returns the timer (cancel it to send nothing)."""
    main_id = threading.main_thread().ident
    assert main_id is not None
    timer = threading.Timer(0.01, signal.pthread_kill, (main_id, signum))
    timer.daemon = True
    timer.start()
    return timer


def _err() -> Console:
    """The console for messages on stderr (rich is imported only when one is printed)."""
    from rich.console import Console

    return Console(stderr=True, highlight=False)


def _interrupted(terminated: list[int]) -> NoReturn:
    """Ctrl-C: exit 130; ``SIGTERM``: exit 143 (nothing half-written either way)."""
    if terminated:
        _err().print("terminated")
        sys.exit(128 + signal.SIGTERM)
    _err().print("interrupted")
    sys.exit(130)


def _internal_error(exc: BaseException) -> NoReturn:
    """A bug: one line naming the exception (the traceback with ``FLOWTWIN_DEBUG=1``)."""
    if os.environ.get("FLOWTWIN_DEBUG"):
        raise exc
    _err().print(f"[bold red]internal error:[/] {type(exc).__name__}: {_escape(str(exc))} "
                 "(set FLOWTWIN_DEBUG=1 for the traceback and please report it)")
    sys.exit(EXIT_INTERNAL_ERROR)


def _escape(text: str) -> str:
    from rich.markup import escape

    return escape(text)
