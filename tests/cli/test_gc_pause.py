"""The ``flowtwin`` process keeps the garbage collector off its start-up and its exit
(:func:`flowtwin.cli.main.run`) and collects as usual afterwards."""

from __future__ import annotations

import subprocess
import sys
import textwrap

PROBE = textwrap.dedent("""
    import gc, json, sys, time, weakref
    import flowtwin.cli.main as m

    m.GC_PAUSE_S = 0.2
    seen = {}

    class Node:
        pass

    def command(argv=None):
        seen["enabled_at_start"] = gc.isenabled()
        time.sleep(0.6)  # past the pause
        seen["enabled_after_pause"] = gc.isenabled()
        seen["frozen"] = gc.get_freeze_count() > 0
        a, b = Node(), Node()
        a.other, b.other = b, a  # a cycle only the collector frees
        probe = weakref.ref(a)
        del a, b
        gc.collect()
        seen["cycle_collected"] = probe() is None
        print(json.dumps(seen))
        sys.exit(0)

    m.main = command
    m.run()
""")


def test_collection_is_off_at_start_and_resumes_after_the_pause() -> None:
    proc = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          timeout=60, check=False)
    assert proc.returncode == 0, proc.stderr
    import json

    seen = json.loads(proc.stdout)
    assert seen == {"enabled_at_start": False, "enabled_after_pause": True, "frozen": True,
                    "cycle_collected": True}


def test_main_in_process_leaves_the_collector_alone() -> None:
    import gc

    from flowtwin.cli.main import main

    before = gc.isenabled(), gc.get_freeze_count()
    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert (gc.isenabled(), gc.get_freeze_count()) == before
