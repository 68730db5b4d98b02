"""A command group that lists its commands by name and help line and imports a command's
module only when the command is resolved (to run it or to show its own help).

``flowtwin`` itself is one (:data:`flowtwin.cli.main.COMMANDS`), and so is ``flowtwin
calibrate``, whose ``pattern`` group needs every pattern's parameters (and the firmware
model) to build its options: ``flowtwin calibrate --help`` lists it without loading them.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any, ClassVar

import typer
from typer.core import TyperGroup

__all__ = ["LazyGroup", "Listing", "lazy_group"]

#: name -> (module under ``flowtwin.cli`` whose ``register(app)`` adds the command, the help
#: line the group's ``--help`` shows for it).
Listing = Mapping[str, tuple[str, str]]


class _Listed(typer.core.TyperCommand):
    """A command known by name and help line only: what the group's ``--help`` lists."""

    def __init__(self, name: str, module: str, help_line: str) -> None:
        super().__init__(name=name, help=help_line, short_help=help_line)
        self.module = module


class LazyGroup(TyperGroup):
    """Lists :attr:`listing` without importing it; a command's module is imported when the
    command is resolved (to run it or show its help)."""

    listing: ClassVar[Listing] = {}

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        # listed commands first, in the listing's order, then those registered directly
        listed = {name: _Listed(name, module, help_line)
                  for name, (module, help_line) in self.listing.items()
                  if name not in self.commands}
        self.commands = {**listed, **self.commands}

    def resolve_command(self, ctx: Any, args: list[str]) -> tuple[str | None, Any, list[str]]:
        name, cmd, rest = super().resolve_command(ctx, args)
        if isinstance(cmd, _Listed):
            cmd = self.load(cmd.module)[cmd.name or ""]
        return name, cmd, rest

    def load(self, module_name: str) -> dict[str, Any]:
        """Import ``flowtwin.cli.<module_name>`` and put its real commands in place."""
        module = importlib.import_module(f"flowtwin.cli.{module_name}")
        sub = typer.Typer(add_completion=False, pretty_exceptions_enable=False)
        module.register(sub)
        group = typer.main.get_group(sub)
        self.commands.update(group.commands)
        return dict(group.commands)


def lazy_group(name: str, listing: Listing) -> type[LazyGroup]:
    """A :class:`LazyGroup` class listing ``listing`` (pass it as ``typer.Typer(cls=...)``)."""
    return type(f"LazyGroup_{name}", (LazyGroup,), {"listing": dict(listing)})
