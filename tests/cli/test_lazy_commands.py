"""The command table of ``flowtwin``: commands load only their own module, help lines match,
``--version``, and a mistyped command or option is a usage error (exit 2, with typer's
suggestion)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import typer.main

from flowtwin import __version__
from flowtwin.cli.main import COMMANDS, LazyGroup, app, main

#: What a help screen, or a plan, must not import (each costs 0.1-1 s of start-up).
HEAVY = ("numba", "scipy", "cv2", "dask", "distributed", "matplotlib", "plotly", "pyarrow",
         "pandas")

_PROBE = r"""
import json, sys
from flowtwin.cli.main import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
print("MODULES " + json.dumps(sorted(m for m in sys.modules if "." not in m)), file=sys.stderr)
"""


def _modules_after(args: list[str]) -> tuple[set[str], subprocess.CompletedProcess[str]]:
    """Top-level modules imported by a fresh ``flowtwin ARGS`` process."""
    proc = subprocess.run([sys.executable, "-c", _PROBE, *args], capture_output=True,
                          text=True, timeout=300, check=False)
    line = [ln for ln in proc.stderr.splitlines() if ln.startswith("MODULES ")]
    assert line, proc.stderr
    return set(json.loads(line[-1][8:])), proc


def _first_paragraph(text: str | None) -> str:
    return " ".join((text or "").split("\n\n")[0].split())


def test_table_help_lines_are_the_commands_own() -> None:
    group = LazyGroup(name="flowtwin")
    for module in dict.fromkeys(m for m, _ in COMMANDS.values()):
        group.load(module)
    real = group.commands
    assert set(real) == set(COMMANDS), "every registered command is in the table and back"
    for name, (_module, line) in COMMANDS.items():
        assert _first_paragraph(real[name].help) == line, name


def test_reproduce_help_lists_the_papers() -> None:
    from flowtwin.cli.reproduce import PAPER_KEYS
    from flowtwin.reproduce import PAPERS

    assert PAPER_KEYS == tuple(PAPERS)


def test_top_level_help_imports_no_command_module() -> None:
    modules, proc = _modules_after(["--help"])
    assert proc.returncode == 0
    for name in COMMANDS:
        assert name in proc.stdout
    assert not modules & {*HEAVY, "numpy"}, sorted(modules & {*HEAVY, "numpy"})


@pytest.mark.parametrize("command", sorted({*COMMANDS}))
def test_command_help_imports_no_heavy_package(command: str) -> None:
    modules, proc = _modules_after([command, "--help"])
    assert proc.returncode == 0, proc.stderr
    assert "Usage" in proc.stdout
    assert not modules & {*HEAVY, "numpy"}, (command, sorted(modules & {*HEAVY, "numpy"}))


@pytest.mark.parametrize("args", [["calibrate", "--help"], ["calibrate", "pattern", "--help"],
                                  ["vision", "measure", "--help"],
                                  ["teststand", "simulate", "--help"]])
def test_subcommand_help_imports_no_numpy(args: list[str]) -> None:
    """Help screens list options: none needs numpy (a 0.05-0.1 s import)."""
    modules, proc = _modules_after(args)
    assert proc.returncode == 0, proc.stderr
    assert "Usage" in proc.stdout
    assert not modules & {*HEAVY, "numpy"}, (args, sorted(modules & {*HEAVY, "numpy"}))


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"flowtwin {__version__}"


@pytest.mark.parametrize(("args", "suggestion"), [
    (["plna", "x.gcode"], "'plan'"),
    (["simulat"], "'simulate'"),
    (["calibrate", "patern"], "'pattern'"),
    (["calibrate", "pattern", "klin"], "'kline'"),
    (["profiles", "lst"], "'list'"),
    (["vision", "mesure"], "'measure'"),
    (["teststand", "analyze"], "'analyse'"),
])
def test_mistyped_command_is_a_usage_error_with_a_suggestion(
        args: list[str], suggestion: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "No such command" in err and f"Did you mean {suggestion}" in err, err
    assert "internal error" not in err


@pytest.mark.parametrize("args", [["--verison"], ["plan", "--jsn", "x.gcode"],
                                  ["calibrate", "pattern", "--kind", "lines"]])
def test_mistyped_option_is_a_usage_error(args: list[str],
                                          capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "No such option" in err and "internal error" not in err, err


def test_a_command_runs_after_the_lazy_lookup() -> None:
    """The click command typer builds for the app resolves every table entry to the real
    command of its module."""
    group = typer.main.get_command(app)
    assert isinstance(group, LazyGroup)
    assert group.list_commands(None) == list(COMMANDS)  # type: ignore[arg-type]
