"""The control loop: control laws, measurement sources, clocks, log and the supervisor.

:mod:`.controllers` (pure control laws [003 §2.3]), :mod:`.measurement` (the source
interface and a synthetic source), :mod:`.burst` and :mod:`.video` (camera and video
sources through vision), :mod:`.clock`, :mod:`.log`, :mod:`.supervisor`.
"""
