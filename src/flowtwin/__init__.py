"""flowtwin: the digital twin of the extrusion system of a filament 3D printer.

Data flows one way (docs/spec.md §5)::

    G-code text -> reader -> moves -> planner -> timeline -> dynamics -> deposition -> result

Internal units are mm, s, N, MPa and °C (docs/spec.md §2); names carry units where ambiguous.
"""

from flowtwin.errors import FlowtwinError

__version__ = "0.1.0"
__all__ = ["FlowtwinError", "__version__"]
