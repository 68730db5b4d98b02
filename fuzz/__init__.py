"""The long-run fuzz campaign (``make fuzz``): hostile inputs through every reader.

``python -m fuzz --documents 1000000`` generates documents from the real reference data
(corpus lines, built-in profiles, Klipper configs, CSVs and images the project writes),
mutates them (real lines with bad numbers, valid-but-odd commands, boundary values, huge
and empty inputs, flipped and truncated bytes) and feeds each to its reader and, for
G-code, on through plan and simulate (and a sample through compensate and the CLI). Any
exception other than the project's own :class:`~flowtwin.errors.FlowtwinError` is a
failure: the document is minimised and saved with its traceback, and becomes a regression
test (``tests/fuzz``).
"""
