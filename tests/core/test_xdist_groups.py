"""``make test`` runs on two workers with ``--dist loadgroup``: the tests that start a service
(OctoPrint, Moonraker, Chromium, a Dask cluster) or share a memoised computation carry an
``xdist_group`` mark so that they run on one worker. pytest 9.2 with pytest-xdist 3.8 drops
those marks without a word (pytest-dev/pytest-xdist#1386; pyproject.toml pins pytest below
9.2): this test runs a small suite the way ``make test`` does and checks that the grouped
tests share a worker.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

SUITE = '''
import json, os, pytest

def _log(name):
    with open(os.environ["GROUP_LOG"], "a") as fh:
        fh.write(json.dumps([name, os.environ.get("PYTEST_XDIST_WORKER")]) + "\\n")

@pytest.mark.parametrize("i", [pytest.param(i, marks=pytest.mark.xdist_group("g"))
                               for i in range(6)])
def test_param_marks(i):
    _log(f"param{i}")

@pytest.mark.xdist_group("h")
@pytest.mark.parametrize("i", range(6))
def test_decorated(i):
    _log(f"decorated{i}")
'''


def test_grouped_tests_run_on_one_worker(tmp_path: Path) -> None:
    (tmp_path / "test_groups.py").write_text(SUITE)
    log = tmp_path / "log.jsonl"
    env = {**os.environ, "GROUP_LOG": str(log)}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-n", "2", "--dist", "loadgroup",
         "-p", "no:randomly", "-p", "no:cacheprovider", "test_groups.py"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    assert len(rows) == 12
    workers: dict[str, set[str]] = {"param": set(), "decorated": set()}
    for name, worker in rows:
        assert worker is not None            # (run by xdist workers, not in process)
        workers[name.rstrip("0123456789")].add(worker)
    assert len(workers["param"]) == 1, workers
    assert len(workers["decorated"]) == 1, workers
