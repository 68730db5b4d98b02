"""The ``flowtwin`` process ends without the interpreter's teardown
(:func:`flowtwin.cli.main.exit_process`) and loses nothing on the way: exit status, exit
handlers, buffered output, threads still running."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest


def _probe(body: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    script = textwrap.dedent("""
        import atexit, sys, threading, time
        from pathlib import Path
        import flowtwin.cli.main as m

        OUT = Path(sys.argv[1])
    """) + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", script, str(tmp_path / "out.txt")],
                          capture_output=True, text=True, timeout=60, check=False)


@pytest.mark.parametrize(("code", "status"), [("None", 0), ("0", 0), ("2", 2), ("143", 143)])
def test_the_exit_status_is_the_commands(tmp_path: Path, code: str, status: int) -> None:
    proc = _probe(f"""
        def command(argv=None):
            sys.exit({code})
        m.main = command
        m.run()
    """, tmp_path)
    assert proc.returncode == status, proc.stderr


def test_a_message_exit_prints_it_and_exits_1(tmp_path: Path) -> None:
    proc = _probe("""
        def command(argv=None):
            sys.exit("no such printer")
        m.main = command
        m.run()
    """, tmp_path)
    assert (proc.returncode, proc.stderr.strip()) == (1, "no such printer")


def test_exit_handlers_run_and_buffered_output_is_flushed(tmp_path: Path) -> None:
    # stdout is a pipe here, so block buffered: the text sits in the buffer at the exit
    proc = _probe("""
        def command(argv=None):
            atexit.register(OUT.write_text, "handler ran")
            sys.stdout.write("x" * 5000 + "end")
            sys.exit(0)
        m.main = command
        m.run()
        print("not reached")
    """, tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "x" * 5000 + "end"
    assert (tmp_path / "out.txt").read_text() == "handler ran"


def test_a_thread_still_running_is_waited_for(tmp_path: Path) -> None:
    proc = _probe("""
        def late():
            time.sleep(0.5)
            OUT.write_text("thread finished")

        def command(argv=None):
            threading.Thread(target=late).start()  # not a daemon: the exit waits for it
            sys.exit(4)
        m.main = command
        m.run()
    """, tmp_path)
    assert proc.returncode == 4, proc.stderr
    assert (tmp_path / "out.txt").read_text() == "thread finished"


def test_a_real_command_through_the_entry_point(tmp_path: Path) -> None:
    out = tmp_path / "plan.json"
    proc = subprocess.run([sys.executable, "-m", "flowtwin", "profiles", "list", "--json"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    out.write_text(proc.stdout)
    import json

    listed = json.loads(out.read_text())
    assert listed  # the whole JSON document arrived, parseable
    bad = subprocess.run([sys.executable, "-m", "flowtwin", "plan", str(tmp_path / "none")],
                         capture_output=True, text=True, timeout=120, check=False)
    assert bad.returncode == 2
    assert "none" in bad.stderr
