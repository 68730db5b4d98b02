"""The layout keeps its rules: every package on the architecture page, small modules, and
no pointer to documents outside the repository."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "flowtwin"
ARCH = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")


def _packages() -> list[Path]:
    return sorted(p.parent for p in SRC.rglob("__init__.py"))


def test_architecture_names_every_package() -> None:
    missing = []
    for pkg in _packages():
        rel = pkg.relative_to(SRC)
        if rel == Path("."):
            continue
        if len(rel.parts) == 1:
            if f"`flowtwin.{rel.parts[0]}`" not in ARCH:
                missing.append(str(rel))
        elif f"{rel.parts[-1]}/" not in ARCH:
            missing.append(str(rel))
    assert not missing, f"docs/architecture.md does not name: {missing}"


def test_no_module_over_600_lines() -> None:
    long = {str(p.relative_to(SRC)): n for p in SRC.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 600}
    assert not long


def test_references_stay_in_the_repository() -> None:
    # the design reference is docs/spec.md, facts about external tools docs/external-tools.md
    bad = re.compile(r"SPEC §|NOTES\.md|\.\./shared|/work/shared")
    hits = [f"{p.relative_to(ROOT)}:{i}" for base in ("src", "tests")
            for p in (ROOT / base).rglob("*") if p.suffix in (".py", ".toml", ".md")
            and p != Path(__file__)
            for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
            if bad.search(line)]
    assert not hits
    spec = (ROOT / "docs" / "spec.md").read_text(encoding="utf-8")
    cited = {m for p in SRC.rglob("*.py")
             for m in re.findall(r"docs/spec\.md §(\d+(?:\.\d+)?)", p.read_text(encoding="utf-8"))}
    for section in cited:
        assert re.search(rf"^#+ {re.escape(section)}\.? ", spec, re.M), section
