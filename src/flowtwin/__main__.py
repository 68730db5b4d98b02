"""``python -m flowtwin``: the ``flowtwin`` command."""

from flowtwin.cli.main import run

run()
