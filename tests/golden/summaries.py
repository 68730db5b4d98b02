"""Golden summaries: the ``--json`` output of ``plan``, ``simulate`` and ``compensate``.

A refactor must leave what a user sees unchanged: this records, for every corpus file and
the built-in example, the JSON object each command prints, and checks a later tree against
the record (every float within 1e-12 of it, relative: the last bits of a sum differ between
CPUs; everything else exactly). A change that is *meant* to change a figure re-records the
files it changes and says why in its commit.

    python tests/golden/summaries.py check [--kind KIND ...] [--file NAME ...]
    python tests/golden/summaries.py record [--kind KIND ...] [--file NAME ...]

The commands run in-process through ``flowtwin.cli.main.main`` with the corpus folder as the
working directory, so the file names in the JSON are bare names. ``compensate`` on every
corpus file takes minutes; ``tests/golden/test_summaries.py`` checks the plan and simulate
records of every file and the compensate records of the three smallest.
"""

from __future__ import annotations

import argparse
import contextlib
import gzip
import importlib.util
import io
import json
import os
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data"
RECORDS = DATA / "golden"
KLIPPER_A = DATA / "klipper" / "A.cfg"
EXAMPLE = "example.gcode"
#: keys that measure this machine's wall clock, not the result (left out of the records)
WALL_CLOCK = ("seconds",)

#: kind -> command line (FILE and OUT replaced); every kind prints one JSON object
KINDS: dict[str, list[str]] = {
    "plan-klipper": ["plan", "FILE", "--klipper-config", str(KLIPPER_A), "--json"],
    "plan-marlin": ["plan", "FILE", "--profile", "generic-marlin", "--json"],
    "simulate": ["simulate", "FILE", "--json"],
    "compensate": ["compensate", "FILE", "-o", "OUT", "--advance", "--slip", "--json"],
}


def corpus_files() -> dict[str, Path]:
    """Every corpus file (decompressed, tests/data/refdata.py) and the built-in example,
    by name, smallest first."""
    spec = importlib.util.spec_from_file_location("flowtwin_golden_refdata",
                                                  DATA / "refdata.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    paths = list(module.corpus_dir().glob("*.gcode"))
    example = module.CACHE / "example" / EXAMPLE
    if not example.exists():
        from flowtwin.gcode.generator import PrintSpec, write_print

        example.parent.mkdir(parents=True, exist_ok=True)
        write_print(example, PrintSpec())
    paths.append(example)
    return {p.name: p for p in sorted(paths, key=lambda p: p.stat().st_size)}


@contextlib.contextmanager
def _cwd(path: Path) -> Iterator[None]:
    old = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def run(kind: str, path: Path) -> str:
    """The JSON the command of ``kind`` prints for ``path`` (run in its folder; normalised)."""
    from flowtwin.cli.main import main

    with tempfile.TemporaryDirectory() as tmp:
        # paths relative to the file's folder: the records hold no absolute path
        argv = [tmp + "/out.gcode" if a == "OUT" else path.name if a == "FILE"
                else os.path.relpath(a, path.parent) if a == str(KLIPPER_A) else a
                for a in KINDS[kind]]
        out, err = io.StringIO(), io.StringIO()
        with _cwd(path.parent), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main(argv)
                code = 0
            except SystemExit as exc:
                code = int(exc.code or 0)
        text = out.getvalue().replace(tmp, "TMP")
    if code != 0:
        return json.dumps({"exit_status": code, "stderr": err.getvalue().strip()},
                          indent=1, sort_keys=True) + "\n"
    summary = json.loads(text)
    for key in WALL_CLOCK:
        summary.pop(key, None)
    return json.dumps(summary, indent=1, sort_keys=True) + "\n"


def record_path(kind: str, name: str) -> Path:
    """Where the record of ``kind`` for corpus file ``name`` lives (gzip, mtime 0)."""
    return RECORDS / kind / (name.removesuffix(".gcode") + ".json.gz")


def read_record(path: Path) -> str | None:
    """The recorded JSON text, or None when there is no record."""
    return gzip.decompress(path.read_bytes()).decode() if path.exists() else None


#: how far a float may be from its record, relative: the last bits of a sum depend on the
#: CPU's vector width (numpy picks its SIMD kernels at run time; an AMD EPYC and an Intel
#: Xeon differ in the 16th digit), a change of a figure does not
REL_TOL = 1e-12


def same(got: str, want: str) -> bool:
    """``got`` is the record ``want``: the same keys, strings, integers and booleans, and
    every float within :data:`REL_TOL` of its record (relative)."""
    def close(a: object, b: object) -> bool:
        if isinstance(a, dict) and isinstance(b, dict):
            return a.keys() == b.keys() and all(close(a[k], b[k]) for k in a)
        if isinstance(a, list) and isinstance(b, list):
            return len(a) == len(b) and all(close(x, y) for x, y in zip(a, b, strict=True))
        if isinstance(a, float) and isinstance(b, float):
            return a == b or abs(a - b) <= REL_TOL * max(abs(a), abs(b))
        return type(a) is type(b) and a == b

    return got == want or close(json.loads(got), json.loads(want))


def write_record(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(gzip.compress(text.encode(), compresslevel=9, mtime=0))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=["record", "check"])
    parser.add_argument("--kind", action="append", choices=sorted(KINDS))
    parser.add_argument("--file", action="append", help="corpus file name (default: all)")
    args = parser.parse_args(argv)
    paths = corpus_files()
    names = args.file or list(paths)
    failed = 0
    for kind in args.kind or list(KINDS):
        for name in names:
            got = run(kind, paths[name])
            path = record_path(kind, name)
            if args.action == "record":
                write_record(path, got)
                print(f"recorded {kind} {name}", flush=True)
            elif (want := read_record(path)) is None or not same(got, want):
                failed += 1
                print(f"DIFFERS  {kind} {name}", flush=True)
            else:
                print(f"same     {kind} {name}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
