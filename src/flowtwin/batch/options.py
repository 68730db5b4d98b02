"""Names and defaults of the batch options (a light module: the CLI builds its help from
these without importing dask, pyarrow or the models)."""

from __future__ import annotations

from typing import Literal

from flowtwin.defaults import DEFAULT_MACHINE

__all__ = ["DEFAULT_ENGINE", "DEFAULT_RETRIES", "DEFAULT_SETUP", "ENGINES", "Engine"]

#: Which model computes a row.
Engine = Literal["plan", "simulate"]

#: Every engine, in the order the CLI lists them.
ENGINES: tuple[Engine, ...] = ("simulate", "plan")

#: The engine used when none is given.
DEFAULT_ENGINE: Engine = "simulate"

#: Extra attempts of a task that raised.
DEFAULT_RETRIES = 2

#: Set-up used when none is given.
DEFAULT_SETUP = DEFAULT_MACHINE
