"""docs/profiles.md documents every key of every profile table."""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.profiles import (
    ArcSettings,
    ArrheniusViscosity,
    AxisAccelerations,
    AxisFeedrates,
    AxisJerks,
    BowdenTube,
    DriveProfile,
    ExponentialViscosity,
    FilamentProfile,
    FirmwareExtruder,
    FirmwareRetraction,
    HotendProfile,
    KlipperLimits,
    MarlinDeltaGeometry,
    MarlinLimits,
    MaterialProfile,
    MaxFeedForceFit,
    Position,
    PressureAdvance,
    PrinterProfile,
    Roller,
    RollerTable,
    SetupProfile,
    SlipOverrides,
    WlfViscosity,
    library_names,
)

DOC = Path(__file__).resolve().parents[2] / "docs" / "profiles.md"
MODELS = [PrinterProfile, KlipperLimits, MarlinLimits, MarlinDeltaGeometry, AxisFeedrates,
          AxisAccelerations,
          AxisJerks, FirmwareExtruder, PressureAdvance, FirmwareRetraction, ArcSettings,
          Position, DriveProfile, SlipOverrides, Roller, MaxFeedForceFit, RollerTable,
          HotendProfile, BowdenTube, MaterialProfile, ExponentialViscosity,
          ArrheniusViscosity, WlfViscosity, FilamentProfile, SetupProfile]


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.__name__)
def test_every_key_is_documented(model: type) -> None:
    text = DOC.read_text(encoding="utf-8")
    section = text.split(f"#### `{model.__name__}`", 1)
    assert len(section) == 2, f"no schema table for {model.__name__}"
    table = section[1].split("####", 1)[0]
    for key in model.model_fields:  # type: ignore[attr-defined]
        assert f"| `{key}` |" in table, f"{model.__name__}.{key} not documented"


def test_every_builtin_is_listed() -> None:
    text = DOC.read_text(encoding="utf-8")
    for name in library_names():
        if not name.startswith("roller-"):
            assert f"`{name}`" in text, name
