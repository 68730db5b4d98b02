"""Install the real slicer the post-processing tests run: Debian's PrusaSlicer and OpenSCAD.

    python tests/postprocess/slicer_install.py

``apt-get install -y prusa-slicer openscad`` (after one ``apt-get update``) when either
command is missing. Idempotent and cheap when both are present (two ``PATH`` look-ups);
concurrent callers (pytest-xdist workers) serialise on a lock file. Prints the path of
``prusa-slicer``.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

PACKAGES = {"prusa-slicer": "prusa-slicer", "openscad": "openscad"}


def _run(cmd: list[str], env: dict[str, str]) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env,
                          timeout=1800)
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-30:])
        raise SystemExit(f"install step failed ({' '.join(cmd)}):\n{tail}")


def install() -> Path:
    """Make sure ``prusa-slicer`` and ``openscad`` are on ``PATH``; return the slicer."""
    lock_path = Path(tempfile.gettempdir()) / "flowtwin-slicer-install.lock"
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        missing = [pkg for exe, pkg in PACKAGES.items() if shutil.which(exe) is None]
        if missing:
            if shutil.which("apt-get") is None:
                raise SystemExit(f"{', '.join(missing)} missing and apt-get is not "
                                 "available: install Debian's prusa-slicer and openscad")
            env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
            _run(["apt-get", "update", "-q"], env)
            _run(["apt-get", "install", "-y", "-q", *missing], env)
        exe = shutil.which("prusa-slicer")
        if exe is None or shutil.which("openscad") is None:
            raise SystemExit("apt-get ran but prusa-slicer or openscad is still missing")
    return Path(exe)


if __name__ == "__main__":
    print(install())
