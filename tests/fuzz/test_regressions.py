"""Every failure the fuzz campaign (``make fuzz``, ``fuzz/``) found, kept as a regression.

``tests/data/fuzz/<target>/`` holds the minimised documents; each must now be read (and
pass through its target's pipelines) or be refused with the project's own error — never
another exception. The campaign's size and findings are in BENCHMARKS.md ("Fuzzing").
"""

from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest

from flowtwin.errors import FlowtwinError

ROOT = Path(__file__).resolve().parents[2]
FOUND = ROOT / "tests" / "data" / "fuzz"
CASES = sorted(p for p in FOUND.glob("*/*") if p.is_file())


@pytest.fixture(scope="module")
def targets() -> dict[str, object]:
    sys.path.insert(0, str(ROOT))
    from fuzz.targets import FACTORIES

    return FACTORIES  # type: ignore[return-value]


def test_the_campaign_has_findings_kept() -> None:
    assert CASES, "no fuzz regressions found under tests/data/fuzz"


@pytest.mark.parametrize("case", CASES, ids=[f"{p.parent.name}/{p.name}" for p in CASES])
def test_fuzz_finding_is_read_or_refused_clearly(case: Path, targets: dict[str, object],
                                                 tmp_path: Path) -> None:
    target = targets[case.parent.name](0)  # type: ignore[operator]
    path = tmp_path / f"doc{target.suffix}"
    path.write_bytes(case.read_bytes())
    try:
        target.run(path, random.Random(0))
    except FlowtwinError as exc:
        assert str(path) in str(exc) or "<" in str(exc), exc
