"""CLI command: ``flowtwin limits`` — the maximum volumetric flow of a set-up.

A thin layer over :mod:`flowtwin.simulation.limits`: the flow where the delivered/commanded
ratio falls below 95 % or the drive's force margin reaches zero (with the melt model of
the hot end), the reason that binds, and a table against temperature. ``--hotend`` and
``--material`` swap parts of the set-up (built-in names or TOML files).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import typer

from flowtwin.errors import ProfileError

if TYPE_CHECKING:
    from flowtwin.profiles.material import MaterialProfile

__all__ = ["limits_command", "register"]


def limits_command(
    profile: str = typer.Option("tronvoll2019", "--profile",
                                help="Set-up: built-in name or setup TOML file."),
    hotend: str | None = typer.Option(None, "--hotend",
                                      help="Use this hot end (name or TOML file)."),
    material: str | None = typer.Option(None, "--material",
                                        help="Use this material (name or TOML file)."),
    temperature: float | None = typer.Option(None, "--temperature",
                                             help="Nozzle temperature, °C (default: the "
                                                  "set-up's, or the middle of a swapped "
                                                  "material's print range)."),
    layer_height: float | None = typer.Option(None, "--layer-height",
                                              help="Add the tip back-pressure of beads at "
                                                   "this layer height, mm (default: free "
                                                   "extrusion, as hot-end makers measure)."),
    step: float = typer.Option(5.0, "--step", help="Temperature step of the table, °C."),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Maximum volumetric flow (mm³/s) of a set-up, why, and against temperature."""
    from flowtwin.cli._common import print_json, table_from_rows
    from flowtwin.errors import ProfileError
    from flowtwin.profiles.machine import load_machine
    from flowtwin.simulation.limits import flow_limit, flow_limit_table

    if not 0.5 <= step <= 50.0:
        raise ProfileError("the temperature step is out of range", field="--step", value=step,
                           allowed="0.5 .. 50 °C")
    setup: Any = _setup(profile)
    update: dict[str, object] = {}
    if hotend is not None:
        update["hotend"] = hotend
    if material is not None:
        update["material"] = material
    if update:
        setup = setup.model_copy(update=update)
    if temperature is not None:
        setup = setup.model_copy(update={"temperature_c": float(temperature)})
    elif material is not None:
        mat = _material(material)
        mid = 0.5 * (mat.print_temp_min_c + mat.print_temp_max_c)
        setup = setup.model_copy(update={"temperature_c": mid})
    machine = load_machine(setup)
    mat_p = machine.material
    lo = max(mat_p.print_temp_min_c, mat_p.viscosity.t_min_c)
    hi = min(mat_p.print_temp_max_c, mat_p.viscosity.t_max_c)
    temps = []
    t = lo
    while t <= hi + 1e-9:
        temps.append(round(t, 6))
        t += step
    main = flow_limit(machine, layer_height_mm=layer_height)
    table = flow_limit_table(machine, temps, layer_height_mm=layer_height)
    out = {**main.as_dict(), "setup": machine.name, "hotend": machine.hotend.name,
           "material": mat_p.name, "drive": machine.drive.name,
           "layer_height_mm": layer_height,
           "table": [r.as_dict() for r in table]}
    if json_output:
        print_json(out)
        return
    from rich.console import Console
    from rich.text import Text

    console = Console()
    cap = main.melt_capacity_mm3_s
    console.print(Text(
        f"{machine.name}: {machine.hotend.name} + {mat_p.name} + {machine.drive.name} at "
        f"{main.temperature_c:g} °C, "
        f"{'free extrusion' if layer_height is None else f'{layer_height:g} mm layers'}"))
    console.print(Text(
        f"maximum volumetric flow {main.max_volumetric_flow_mm3_s:.2f} mm³/s — {main.reason}"
        f" (melt {main.at_limit.melt_temperature_c:.1f} °C, force "
        f"{main.at_limit.feed_force_n:.1f} N, slip {100 * main.at_limit.slip:.1f} %)"
        + ("" if cap is None else f"; the hot end's melt capacity is {cap:.2f} mm³/s")
        + ("" if main.melt_model else "; no melt model (the hot end has no melt zone "
           "or the material no thermal data): the melt is taken at the set temperature")))
    rows = [[f"{r.temperature_c:g}", f"{r.max_volumetric_flow_mm3_s:.2f}", r.reason,
             f"{r.at_limit.melt_temperature_c:.1f}", f"{r.at_limit.feed_force_n:.1f}",
             "-" if r.melt_capacity_mm3_s is None else f"{r.melt_capacity_mm3_s:.2f}"]
            for r in table]
    console.print(table_from_rows("against temperature",
                                  ["°C", "max mm³/s", "binds", "melt °C", "force N",
                                   "melt capacity mm³/s"], rows))


def _material(ref: str) -> MaterialProfile:
    from flowtwin.profiles import load_builtin, load_profile
    from flowtwin.profiles.material import MaterialProfile

    mat = load_profile(ref, "material") if ref.endswith(".toml") else load_builtin(
        ref, "material")
    if not isinstance(mat, MaterialProfile):
        raise ProfileError("not a material profile", field="--material", value=ref,
                           allowed="a material from `flowtwin profiles list`")
    return mat


def _setup(ref: str) -> object:
    """The set-up profile; a file's relative part paths made absolute (so parts can be
    swapped in a copy)."""
    from pathlib import Path

    from flowtwin.profiles import load_builtin, load_profile

    if not (ref.endswith(".toml") or Path(ref).is_file()):
        return load_builtin(ref, "setup")
    setup = load_profile(ref, "setup")
    base = Path(ref).resolve().parent
    update = {k: str(base / v) for k in ("printer", "drive", "hotend", "material", "filament")
              if (v := getattr(setup, k)).endswith(".toml") and not Path(v).is_absolute()}
    return setup.model_copy(update=update)


def register(app: typer.Typer) -> None:
    """Add the ``limits`` command to ``app``."""
    app.command("limits")(limits_command)
