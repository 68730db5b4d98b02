"""Fixtures of the control tests: a Marlin-like responder on a real pty pair."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


@dataclass
class PtyFirmware:
    """A responder process on the master side; ``path`` is the slave device to open."""

    path: str
    log: Path
    proc: subprocess.Popen[bytes]

    def received(self) -> list[str]:
        """Every line the responder received (raw, with N and checksum)."""
        return self.log.read_text(encoding="ascii").splitlines() if self.log.exists() else []


@pytest.fixture
def marlin_pty(tmp_path: Path) -> Iterator[Callable[..., PtyFirmware]]:
    """Factory: ``marlin_pty("--corrupt", "2")`` starts a responder and returns its pty."""
    started: list[tuple[PtyFirmware, int]] = []

    def start(*options: str) -> PtyFirmware:
        master, slave = os.openpty()
        log = tmp_path / f"responder{len(started)}.log"
        proc = subprocess.Popen(
            [sys.executable, str(HERE / "marlin_responder.py"), str(master), "--log", str(log),
             *options], pass_fds=(master,))
        os.close(master)  # the responder owns the master side now
        fw = PtyFirmware(os.ttyname(slave), log, proc)
        started.append((fw, slave))
        return fw

    yield start
    for fw, slave in started:
        if fw.proc.poll() is None:
            fw.proc.terminate()
        fw.proc.wait(timeout=5)
        os.close(slave)
