"""CLI commands: ``flowtwin teststand simulate`` and ``flowtwin teststand analyse``.

A thin layer over :mod:`flowtwin.teststand`: ``simulate`` runs the procedure of [000 §3] on
a roller of [000] (or a drive profile's roller) and writes the records as CSV (schema in
docs/teststand.md); ``analyse`` evaluates any such file — simulated or from a real stand —
and prints the fits of [000 Eqs. 6, 8, 9, Figs. 4–8] with uncertainties, compared with
[000 Table 3] where the roller id is 1–7.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.console import Console
from rich.table import Table
from rich.text import Text

from flowtwin.errors import ProfileError
from flowtwin.teststand.series import PAPER_PINCH_FORCES_N, PAPER_SPEEDS_MM_S, SlipLaw

if TYPE_CHECKING:
    from flowtwin.profiles import Roller
    from flowtwin.teststand.model import Instrument, Procedure

__all__ = ["register", "resolve_roller", "simulate_report"]

teststand_app = typer.Typer(
    name="teststand",
    help="Virtual filament-drive test stand [000 §3] and evaluation of test-stand records.",
    no_args_is_help=True,
)


def _floats(text: str, option: str) -> tuple[float, ...]:
    try:
        values = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError as exc:
        raise ProfileError("not a comma-separated list of numbers", field=option, value=text,
                           allowed="e.g. 10,20,30") from exc
    if not values:
        raise ProfileError("empty list", field=option, value=text, allowed="one or more numbers")
    return values


def resolve_roller(roller: int | None, drive: str | None) -> Roller:
    """The roller to put on the stand: a number of [000] or a drive profile's roller.

    Parameters
    ----------
    roller
        Roller number 1–7 of [000], or ``None``.
    drive
        Built-in drive name or drive ``.toml`` file, or ``None``.

    Returns
    -------
    Roller

    Raises
    ------
    ProfileError
        Neither or both given, an unknown roller number, or a bad drive profile.
    """
    from flowtwin.profiles import DriveProfile, load_builtin, load_profile, load_rollers

    if (roller is None) == (drive is None):
        raise ProfileError("give exactly one of --roller (1-7) or --drive (profile)",
                           field="--roller/--drive", value=(roller, drive),
                           allowed="one of them")
    rollers = load_rollers()
    if roller is not None:
        if roller not in rollers:
            raise ProfileError("unknown roller number", field="--roller", value=roller,
                               allowed=", ".join(str(k) for k in sorted(rollers)))
        return rollers[roller]
    assert drive is not None
    profile = load_profile(drive, "drive") if drive.endswith(".toml") else \
        load_builtin(drive, "drive")
    assert isinstance(profile, DriveProfile)
    return profile.resolve_roller(rollers)


def simulate_report(out: Path, *, roller: Roller, law: SlipLaw, seed: int,
                    procedure: Procedure, k_p: float, max_force_scatter: float,
                    instrument: Instrument | None = None,
                    roller_id: str | None = None) -> dict[str, Any]:
    """Simulate a campaign, write it to ``out`` and return a JSON-able summary.

    Parameters
    ----------
    out
        CSV file to write (atomically).
    roller
        Roller on the stand.
    law
        Slip-gradient law (:class:`~flowtwin.teststand.SlipLaw`).
    seed
        Noise seed.
    procedure
        Parameter grid and procedure.
    k_p
        Stand slip offset, fraction.
    max_force_scatter
        Relative per-record scatter of the maximum feed force.
    instrument
        Sensors (default: [000]'s).
    roller_id
        Label in the records (default: roller number or ``custom``).

    Returns
    -------
    dict
        ``file``, ``roller_id``, ``law``, ``seed``, ``records``, ``rows``, the grid and the
        instrument.
    """
    from flowtwin.teststand import DriveUnderTest, simulate_campaign, write_records_csv
    from flowtwin.teststand.model import Instrument

    inst = instrument or Instrument()
    drive = DriveUnderTest.from_roller(roller, law=law, k_p=k_p,
                                       max_force_scatter=max_force_scatter, roller_id=roller_id)
    records = simulate_campaign(drive, seed=seed, procedure=procedure, instrument=inst)
    comment = (f"virtual stand: roller {drive.roller_id} ({roller.label}), law {law.value}, "
               f"seed {seed}, k_p {k_p:g}, max-force scatter {max_force_scatter:g}\n"
               f"instrument: force sigma {inst.force_sigma_n:g} N, speed sigma "
               f"{inst.speed_sigma_mm_s:g} mm/s, {inst.sample_rate_hz:g} samples/s")
    rows = write_records_csv(out, records, comment=comment)
    return {"file": str(out), "roller_id": drive.roller_id, "law": law.value, "seed": seed,
            "records": len(records), "rows": rows,
            "pinch_forces_N": list(procedure.pinch_forces_n),
            "speeds_mm_s": list(procedure.speeds_mm_s), "repeats": procedure.repeats,
            "instrument": {"force_sigma_N": inst.force_sigma_n,
                           "speed_sigma_mm_s": inst.speed_sigma_mm_s,
                           "sample_rate_hz": inst.sample_rate_hz}}


@teststand_app.command("simulate")
def simulate_command(
    out: Path = typer.Argument(..., help="CSV file to write."),
    roller: int | None = typer.Option(None, "--roller", help="Roller 1-7 of [000]."),
    drive: str | None = typer.Option(None, "--drive",
                                     help="Drive profile (name or .toml) whose roller to use."),
    law: SlipLaw = typer.Option(SlipLaw.COMBINED, "--law", help="Slip-gradient law."),
    seed: int = typer.Option(0, "--seed", help="Seed of the instrument noise."),
    pinch_forces: str = typer.Option(",".join(f"{f:g}" for f in PAPER_PINCH_FORCES_N),
                                     "--pinch-forces", help="Set pinch forces, N."),
    speeds: str = typer.Option(",".join(f"{v:g}" for v in PAPER_SPEEDS_MM_S), "--speeds",
                               help="Set feed velocities, mm/s."),
    repeats: int = typer.Option(3, "--repeats", help="Records per parameter set."),
    k_p_pct: float = typer.Option(0.63, "--k-p-pct",
                                  help="Slip offset of the stand, % ([000 Fig. 9a]: 0.63)."),
    max_force_scatter: float = typer.Option(
        0.0, "--max-force-scatter",
        help="Relative per-record scatter of the maximum feed force (e.g. 0.08)."),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Run the test-stand procedure of [000 §3] on a roller and write the records as CSV."""
    from flowtwin.teststand.model import Procedure

    chosen = resolve_roller(roller, drive)
    procedure = Procedure(pinch_forces_n=_floats(pinch_forces, "--pinch-forces"),
                          speeds_mm_s=_floats(speeds, "--speeds"), repeats=repeats)
    report = simulate_report(out, roller=chosen, law=law, seed=seed, procedure=procedure,
                             k_p=k_p_pct / 100.0, max_force_scatter=max_force_scatter)
    if json_output:
        typer.echo(json.dumps(report))
        return
    Console().print(Text(f"wrote {report['rows']} rows ({report['records']} records, roller "
                         f"{report['roller_id']}, law {report['law']}) to {out}"))


def _fmt(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def _print_summary(summary: dict[str, Any], console: Console) -> None:
    for roller in summary["rollers"]:
        table = Table(title=Text(f"roller {roller['roller_id']}: {roller['records']} records "
                                 f"({roller['rejected']['count']} without slip regression)"),
                      header_style="bold")
        for col in ("quantity", "value", "± (1σ)"):
            table.add_column(col)
        pl, vl, mf = roller["pinch_law"], roller["velocity_law"], roller["max_force"]
        if pl:
            table.add_row("k_s (Eq. 6)", f"{_fmt(pl['k_s_pct_N'])} %·N", _fmt(pl["k_s_err_pct_N"]))
            table.add_row("k_inf (Eq. 6)", f"{_fmt(pl['k_inf_pct_per_N'])} %/N",
                          _fmt(pl["k_inf_err_pct_per_N"]))
            table.add_row("F_p,min (Eq. 9)", f"{_fmt(pl['fp_min_N'])} N",
                          _fmt(pl["fp_min_err_N"]))
        if vl:
            table.add_row("a (Eq. 8)", f"{_fmt(vl['a_pct_per_N'])} %/N",
                          _fmt(vl["a_err_pct_per_N"]))
            if vl["velocity_dependent"]:
                table.add_row("b (Eq. 8)", f"{_fmt(vl['b_pct_per_N'])} %/N",
                              _fmt(vl["b_err_pct_per_N"]))
                table.add_row("c (Eq. 8)", f"{_fmt(vl['c_s_per_mm'])} s/mm",
                              _fmt(vl["c_err_s_per_mm"]))
            table.add_row("velocity law", Text(vl["reason"]), "")
        if mf:
            table.add_row("F_f,max fit", Text(f"{_fmt(mf['c2_per_N'])}·F_p² + {_fmt(mf['c1'])}"
                                              f"·F_p + {_fmt(mf['c0_N'])} N"),
                          Text(", ".join(_fmt(e) for e in mf["errors"])))
        table.add_row("median R²", _fmt(roller["r_squared"]["median"]), "")
        for name, why in roller["problems"].items():
            table.add_row(Text(name), Text(f"not fitted: {why}"), "")
        console.print(table)
        if "comparison" in roller:
            comp = Table(title=Text(f"roller {roller['roller_id']} against [000 Table 3]"),
                         header_style="bold")
            for col in ("parameter", "published", "tolerance", "recovered", "pass"):
                comp.add_column(col)
            for c in roller["comparison"]:
                comp.add_row(Text(f"{c['parameter']} ({c['unit']})"), _fmt(c["published"]),
                             _fmt(c["tolerance"]), _fmt(c["recovered"]),
                             "ok" if c["pass"] else "NO")
            console.print(comp)


@teststand_app.command("analyse")
def analyse_command(
    records: Path = typer.Argument(..., help="Test-stand CSV file (schema: docs/teststand.md)."),
    figures: Path | None = typer.Option(None, "--figures", help="Write figures to this folder."),
    compare: bool = typer.Option(True, "--compare/--no-compare",
                                 help="Compare rollers 1-7 with [000 Table 3]."),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Evaluate test-stand records: Eq. 6, 8, 9 and the maximum-force fit of [000]."""
    from flowtwin.teststand.summary import analyse_file

    summary = analyse_file(records, figures_dir=figures, compare=compare)
    if json_output:
        typer.echo(json.dumps(summary))
        return
    _print_summary(summary, Console())


def register(app: typer.Typer) -> None:
    """Add the ``teststand`` command group to ``app``."""
    app.add_typer(teststand_app, name="teststand")
