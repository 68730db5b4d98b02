"""Entry point of the ``flowtwin`` command.

Each command group lives in its own module with a ``register(app)`` function; this module
only assembles them and turns :class:`~flowtwin.errors.FlowtwinError` into a one-line
message on stderr and a non-zero exit status (never a traceback to a user).
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import threading
from typing import NoReturn, Protocol, cast

import typer
from rich.console import Console
from rich.markup import escape

from flowtwin.errors import FlowtwinError, file_access_error

__all__ = ["app", "main"]

#: Modules under ``flowtwin.cli`` that contribute commands (each has ``register(app)``).
COMMAND_MODULES = ("plan", "simulate", "compensate", "demo", "batch", "profiles",
                   "calibrate", "teststand", "reproduce", "control", "vision", "limits")

EXIT_USER_ERROR = 2
EXIT_INTERNAL_ERROR = 3


def build_app() -> typer.Typer:
    """Create the typer application with every command group registered."""
    application = typer.Typer(
        name="flowtwin",
        help="Digital twin of the extrusion system of a filament 3D printer.",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
    )
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"flowtwin.cli.{name}")
        module.register(application)
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
    err = Console(stderr=True, highlight=False)
    terminated: list[int] = []

    def terminate(signum: int, frame: object) -> None:
        # unwind like Ctrl-C, so outputs being written are dropped whole
        terminated.append(signum)
        raise KeyboardInterrupt

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, terminate)
    try:
        # standalone_mode=False returns typer.Exit codes instead of exiting with them
        code = app(args=argv, standalone_mode=False)
    except FlowtwinError as exc:
        err.print(f"[bold red]error:[/] {escape(str(exc))}", markup=True, soft_wrap=True)
        sys.exit(EXIT_USER_ERROR)
    except OSError as exc:
        if exc.filename is None:  # not about a file the user named: a bug, reported below
            _internal_error(err, exc)
        err.print(f"[bold red]error:[/] {escape(str(file_access_error(exc, writing=None)))}",
                  markup=True, soft_wrap=True)
        sys.exit(EXIT_USER_ERROR)
    except KeyboardInterrupt:
        _interrupted(err, terminated)
    except SystemExit:
        raise
    except Exception as exc:  # last line of defence for the user
        kind = _click_kind(exc)
        if kind == "ClickException":  # a usage error: typer's message, exit 2
            usage = cast(_ClickError, exc)
            usage.show()
            sys.exit(usage.exit_code)
        if kind == "Abort":  # click's form of Ctrl-C (or of SIGTERM, through the handler)
            _interrupted(err, terminated)
        _internal_error(err, exc)
    else:
        if code == 130:  # typer's answer to a KeyboardInterrupt (Ctrl-C or our SIGTERM)
            _interrupted(err, terminated)
        sys.exit(code if isinstance(code, int) else 0)


def _interrupted(err: Console, terminated: list[int]) -> NoReturn:
    """Ctrl-C: exit 130; ``SIGTERM``: exit 143 (nothing half-written either way)."""
    if terminated:
        err.print("terminated")
        sys.exit(128 + signal.SIGTERM)
    err.print("interrupted")
    sys.exit(130)


def _internal_error(err: Console, exc: BaseException) -> NoReturn:
    """A bug: one line naming the exception (the traceback with ``FLOWTWIN_DEBUG=1``)."""
    if os.environ.get("FLOWTWIN_DEBUG"):
        raise exc
    err.print(f"[bold red]internal error:[/] {type(exc).__name__}: {escape(str(exc))} "
              "(set FLOWTWIN_DEBUG=1 for the traceback and please report it)")
    sys.exit(EXIT_INTERNAL_ERROR)
