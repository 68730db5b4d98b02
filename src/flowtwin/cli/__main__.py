"""``python -m flowtwin.cli``: the ``flowtwin`` command."""

from flowtwin.cli.main import run

run()
