"""Install the real browser the report tests drive: Debian's Chromium and Playwright for Python.

    python tests/report/browser_install.py

* ``chromium`` from Debian's packages (``apt-get install -y chromium``) when
  ``/usr/bin/chromium`` is missing (``apt-get update`` first, once);
* ``playwright`` from PyPI into the running interpreter's environment when it cannot be
  imported. Playwright's own browser download (``playwright install``) is never used: the
  tests point Playwright at the system Chromium.

Idempotent and cheap when both are present (a file check and an import); concurrent callers
(pytest-xdist workers) serialise on a lock file. Prints the Chromium path.
"""

from __future__ import annotations

import fcntl
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

CHROMIUM = Path(os.environ.get("FLOWTWIN_CHROMIUM", "/usr/bin/chromium"))
PLAYWRIGHT = "playwright>=1.45"


def _run(cmd: list[str], env: dict[str, str] | None = None) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env,
                          timeout=1800)
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-30:])
        raise SystemExit(f"install step failed ({' '.join(cmd)}):\n{tail}")


def install() -> Path:
    """Make sure Chromium and Playwright are there; return Chromium's path."""
    lock_path = Path(tempfile.gettempdir()) / "flowtwin-browser-install.lock"
    with open(lock_path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not CHROMIUM.exists():
            if shutil.which("apt-get") is None:
                raise SystemExit(f"{CHROMIUM} is missing and apt-get is not available: "
                                 "install Debian's chromium package")
            env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
            _run(["apt-get", "update", "-q"], env)
            _run(["apt-get", "install", "-y", "-q", "chromium"], env)
            if not CHROMIUM.exists():
                raise SystemExit(f"apt-get installed chromium but {CHROMIUM} is missing")
        if importlib.util.find_spec("playwright") is None:
            _run([sys.executable, "-m", "pip", "install", "-q", PLAYWRIGHT])
    return CHROMIUM


if __name__ == "__main__":
    print(install())
