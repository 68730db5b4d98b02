"""Entry point of the ``flowtwin`` command.

Each command group lives in its own module with a ``register(app)`` function; this module
only assembles them and turns :class:`~flowtwin.errors.FlowtwinError` into a one-line
message on stderr and a non-zero exit status (never a traceback to a user).
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import NoReturn

import typer
from rich.console import Console
from rich.markup import escape

from flowtwin.errors import FlowtwinError, file_access_error

__all__ = ["app", "main"]

#: Modules under ``flowtwin.cli`` that contribute commands (each has ``register(app)``).
COMMAND_MODULES = ("plan", "simulate", "compensate", "demo", "batch", "profiles",
                   "calibrate", "teststand", "reproduce", "control", "vision")

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


def main(argv: list[str] | None = None) -> None:
    """Run the CLI; user errors exit 2 with a message, internal errors exit 3."""
    err = Console(stderr=True, highlight=False)
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
        err.print("interrupted")
        sys.exit(130)
    except SystemExit:
        raise
    except Exception as exc:  # last line of defence for the user
        import click

        if isinstance(exc, click.exceptions.ClickException):
            exc.show()
            sys.exit(exc.exit_code)
        if isinstance(exc, click.exceptions.Abort):
            err.print("aborted")
            sys.exit(1)
        _internal_error(err, exc)
    else:
        sys.exit(code if isinstance(code, int) else 0)


def _internal_error(err: Console, exc: BaseException) -> NoReturn:
    """A bug: one line naming the exception (the traceback with ``FLOWTWIN_DEBUG=1``)."""
    if os.environ.get("FLOWTWIN_DEBUG"):
        raise exc
    err.print(f"[bold red]internal error:[/] {type(exc).__name__}: {escape(str(exc))} "
              "(set FLOWTWIN_DEBUG=1 for the traceback and please report it)")
    sys.exit(EXIT_INTERNAL_ERROR)
