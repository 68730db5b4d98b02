"""What a user sees is unchanged: the ``--json`` summaries against their records.

The records (tests/data/golden) were written by ``tests/golden/summaries.py record``; a
change meant to move a figure re-records and says why. ``compensate`` is checked here on
the three smallest files (the script checks all of them: minutes).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location("flowtwin_golden_summaries",
                                               Path(__file__).with_name("summaries.py"))
assert _spec is not None and _spec.loader is not None
golden = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = golden
_spec.loader.exec_module(golden)

NAMES = [p.name.removesuffix(".json.gz") + ".gcode"
         for p in sorted((golden.RECORDS / "simulate").glob("*.json.gz"))]
SMALLEST = ("kisslicer_1.1.0.5_thinbox_small.gcode", "bambustudio_1.07_2colour_cube_small.gcode",
            "prusaslicer_2.8.1_minicube_small.gcode")


@pytest.fixture(scope="module")
def paths() -> dict[str, Path]:
    return golden.corpus_files()


def test_every_corpus_file_and_the_example_have_records() -> None:
    assert len(NAMES) == 19 and golden.EXAMPLE in NAMES


@pytest.mark.corpus
@pytest.mark.parametrize("kind", ["plan-klipper", "plan-marlin", "simulate"])
@pytest.mark.parametrize("name", NAMES)
def test_summary_matches_its_record(kind: str, name: str, paths: dict[str, Path]) -> None:
    want = golden.read_record(golden.record_path(kind, name))
    assert want is not None
    assert golden.same(golden.run(kind, paths[name]), want)


@pytest.mark.corpus
@pytest.mark.slow
@pytest.mark.parametrize("name", SMALLEST)
def test_compensate_summary_matches_its_record(name: str, paths: dict[str, Path]) -> None:
    want = golden.read_record(golden.record_path("compensate", name))
    assert want is not None
    assert golden.same(golden.run("compensate", paths[name]), want)


def test_the_comparison_allows_the_last_bits_and_nothing_more() -> None:
    rec = '{"a": 0.340324693835605, "b": [1, "x", true], "c": {"d": 2.0}}'
    assert golden.same('{"a": 0.34032469383560493, "b": [1, "x", true], "c": {"d": 2.0}}', rec)
    for other in ('{"a": 0.34032469384, "b": [1, "x", true], "c": {"d": 2.0}}',
                  '{"a": 0.340324693835605, "b": [2, "x", true], "c": {"d": 2.0}}',
                  '{"a": 0.340324693835605, "b": [1, "y", true], "c": {"d": 2.0}}',
                  '{"a": 0.340324693835605, "b": [1, "x", 1], "c": {"d": 2.0}}',
                  '{"a": 0.340324693835605, "b": [1, "x", true], "c": {"e": 2.0}}',
                  '{"a": 0.340324693835605, "b": [1, "x", true, 4], "c": {"d": 2.0}}'):
        assert not golden.same(other, rec)
