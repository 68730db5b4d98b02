"""Shared fixtures of the compensation tests: the built-in example print, in both E modes."""

from __future__ import annotations

import re
from collections.abc import Callable
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest

from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import read_gcode

_E = re.compile(r"E(-?\d*\.?\d+)")


def to_absolute_e(text: str) -> str:
    """The same print with absolute E (``M82``), reset by ``G92 E0`` at every layer."""
    out = []
    e = Decimal(0)
    for line in text.splitlines():
        if line.startswith("M83"):
            out.append("M82 ; absolute E")
            continue
        if line.startswith(";LAYER_CHANGE"):
            out.append(line)
            out.append("G92 E0")
            e = Decimal(0)
            continue
        m = _E.search(line) if line[:2] in ("G1", "G0", "G2", "G3") else None
        if m:
            e += Decimal(m.group(1))
            line = line[:m.start(1)] + f"{e:.5f}" + line[m.end(1):]
        out.append(line)
    return "\n".join(out) + "\n"


def _commanded_e(path: Path) -> float:
    mv = read_gcode(path).moves
    return float(np.sum(mv["de"][(mv["kind"] & MoveKind.FW_RETRACT) == 0]))


@pytest.fixture(scope="session")
def commanded_e() -> Callable[[Path], float]:
    """Total E a G-code file writes (firmware retractions excluded), mm."""
    return _commanded_e


@pytest.fixture(scope="session")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in example print (2 layers: small and fast), relative E."""
    path = tmp_path_factory.mktemp("example") / "example.gcode"
    write_print(path, PrintSpec(layers=2))
    return path


@pytest.fixture(scope="session")
def example_abs(tmp_path_factory: pytest.TempPathFactory, example: Path) -> Path:
    """The same print with absolute E."""
    path = tmp_path_factory.mktemp("example_abs") / "example_abs.gcode"
    path.write_text(to_absolute_e(example.read_text()))
    return path
