"""TOML profile fragments with uncertainty comments."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from flowtwin.calibration.fragment import format_toml_value, render_fragment, write_fragment
from flowtwin.errors import CalibrationError
from flowtwin.profiles.material import ExponentialViscosity


def test_round_trip_with_uncertainty_comments() -> None:
    values = {"law": "exponential", "mu0_pa_s": 26718123.456, "b_per_c": 0.0536481234,
              "t_min_c": 190.0, "t_max_c": 230.0}
    text = render_fragment("viscosity", values, stderr={"mu0_pa_s": 1.2e6, "b_per_c": 3.1e-4},
                           header=["fitted to sweep.csv", ""])
    assert text.startswith("# fitted to sweep.csv\n#\n[viscosity]\n")
    lines = {line.split("=")[0].strip(): line for line in text.splitlines() if "=" in line}
    assert lines["b_per_c"].endswith("# ± 0.00031 (1σ)")
    assert "#" not in lines["t_min_c"]
    parsed = tomllib.loads(text)["viscosity"]
    assert parsed["law"] == "exponential"
    # 7 significant digits written
    assert parsed["mu0_pa_s"] == pytest.approx(26718123.456, rel=5e-7)
    assert parsed["b_per_c"] == pytest.approx(0.0536481234, rel=5e-7)
    assert isinstance(parsed["t_min_c"], float) and parsed["t_min_c"] == 190.0
    # the fragment is a valid [viscosity] table of a material profile
    ExponentialViscosity.model_validate(parsed)


@pytest.mark.parametrize(("value", "text"), [
    (1.0, "1.0"), (1e30, "1e+30"), (0.000123, "0.000123"), (True, "true"), (3, "3"),
    ('a "q"', '"a \\"q\\""'),
])
def test_format_toml_value(value: object, text: str) -> None:
    assert format_toml_value(value) == text
    assert tomllib.loads(f"v = {text}")["v"] == pytest.approx(value) if not isinstance(
        value, str) else tomllib.loads(f"v = {text}")["v"] == value


def test_non_finite_value_is_refused() -> None:
    with pytest.raises(CalibrationError, match="not finite"):
        render_fragment("t", {"x": float("nan")})


def test_write_is_atomic_and_checked(tmp_path: Path) -> None:
    out = tmp_path / "frag.toml"
    text = render_fragment("strand", {"model": "tractrix", "r_mm": 0.3})
    write_fragment(out, text)
    assert out.read_text() == text
    with pytest.raises(tomllib.TOMLDecodeError):
        write_fragment(tmp_path / "bad.toml", "[strand\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frag.toml"]
