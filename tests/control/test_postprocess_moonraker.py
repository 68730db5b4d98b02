"""``flowtwin postprocess --moonraker URL`` reads the live configuration of a real Klipper
host (Kalico klippy behind Moonraker 0.11.0, the ``moonraker_server`` fixture) and plans
with it exactly as with the ``printer.cfg`` that host runs."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.service, pytest.mark.xdist_group("moonraker")]

DATA = Path(__file__).resolve().parents[1] / "data"
CLI = [sys.executable, "-c", "from flowtwin.cli.main import main; main()"]


def _corpus(name: str, dest: Path) -> Path:
    dest.write_bytes(gzip.decompress((DATA / "corpus" / f"{name}.gcode.gz").read_bytes()))
    return dest


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=900,
                          check=False)


def test_moonraker_configuration_plans_like_the_hosts_printer_cfg(moonraker_server,
                                                                  tmp_path: Path) -> None:
    live = _corpus("prusaslicer_2.7.4_vase", tmp_path / "live.gcode")
    filed = _corpus("prusaslicer_2.7.4_vase", tmp_path / "filed.gcode")
    cfg = moonraker_server.workdir / "printer.cfg"
    proc = _run("postprocess", "--moonraker", moonraker_server.url, str(live), "--json")
    assert proc.returncode == 0, proc.stderr
    side = json.loads(proc.stdout)
    assert side["printer"]["source"] == "moonraker"
    assert moonraker_server.url in side["printer"]["label"]
    assert _run("postprocess", "--klipper-config", str(cfg), str(filed)).returncode == 0
    plan = json.loads(_run("plan", "--klipper-config", str(cfg), str(live), "--json").stdout)
    assert side["times"]["total_s"] == pytest.approx(plan["total_time_s"], rel=0, abs=1e-9)
    # the same file as with the host's own printer.cfg, but for the flowtwin line that
    # names where the configuration came from
    a, b = live.read_text().splitlines(), filed.read_text().splitlines()
    assert a[:-1] == b[:-1] and a[-1] != b[-1] and moonraker_server.url in a[-1]


def test_an_unreachable_moonraker_is_a_clear_error_and_the_file_is_untouched(
        tmp_path: Path) -> None:
    gcode = _corpus("prusaslicer_2.7.4_vase", tmp_path / "part.gcode")
    before = gcode.read_bytes()
    proc = _run("postprocess", "--moonraker", "http://127.0.0.1:9", str(gcode))
    assert proc.returncode == 2
    assert "cannot reach Moonraker" in proc.stderr and "127.0.0.1:9" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert gcode.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["part.gcode"]
