"""Output on a full disk or a read-only folder: an error naming the path and the cause (#21).

The file systems are real: a 16 KiB tmpfs mounted in a private mount namespace
(``unshare -r -m``, util-linux), filled by the command's own output, and the same tmpfs
remounted read-only. The previous file at the output path must stay byte-identical and no
temporary file may be left behind.
"""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from flowtwin.gcode.generator import PrintSpec, write_print

CLI = f"{shlex.quote(sys.executable)} -c 'from flowtwin.cli.main import main; main()'"


@pytest.fixture(scope="module")
def gcode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("in") / "demo.gcode"
    write_print(path, PrintSpec())
    return path


def _in_namespace(script: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["unshare", "-r", "-m", "sh", "-c", script], capture_output=True,
                          text=True, timeout=300, check=False)


def _listing(out: str) -> dict[str, object]:
    return json.loads(out.strip().splitlines()[-1])


REPORT = (f"{shlex.quote(sys.executable)} -c 'import json, os, sys; d = sys.argv[1]; "
          "print(json.dumps({\"files\": sorted(os.listdir(d)), "
          "\"old\": open(os.path.join(d, \"out.gcode\")).read()}))'")


@pytest.mark.parametrize("how", ["full", "read-only"])
def test_output_that_cannot_be_written_is_a_clear_error(tmp_path: Path, gcode: Path,
                                                        how: str) -> None:
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    out = mnt / "out.gcode"
    remount = (f"mount -o remount,ro {mnt} && " if how == "read-only" else "")
    script = (f"mount -t tmpfs -o size=16k tmpfs {mnt} && printf 'old output\\n' > {out} && "
              f"{remount}{CLI} compensate {gcode} -o {out} --slip; echo \"rc=$?\" >&2; "
              f"{REPORT} {mnt}")
    proc = _in_namespace(script)
    assert "rc=2" in proc.stderr, proc.stderr
    cause = ("No space left on device (ENOSPC)" if how == "full"
             else "Read-only file system (EROFS)")
    assert f"error: {out}: cannot write the file: {cause}" in proc.stderr, proc.stderr
    assert "internal error" not in proc.stderr and "Traceback" not in proc.stderr
    state = _listing(proc.stdout)
    assert state == {"files": ["out.gcode"], "old": "old output\n"}
