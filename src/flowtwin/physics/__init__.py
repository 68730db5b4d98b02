"""Physics models of the extrusion system as small pure functions (docs/spec.md §3).

One concept per module, each function citing its seed equation:

* :mod:`~flowtwin.physics.drive` — slip, pinch force, maximum feed force, grinding [000];
* :mod:`~flowtwin.physics.compliance` — filament column compliance, Bowden tube [002, 001];
* :mod:`~flowtwin.physics.viscosity` — melt viscosity laws [002];
* :mod:`~flowtwin.physics.nozzle` — pressure drops, resistance, forces [002, 001];
* :mod:`~flowtwin.physics.lag` — the lag factor ``K`` and the one exact lag step [001, 002];
* :mod:`~flowtwin.physics.deposition` — bead area and width, ooze, blobs [001, 003];
* :mod:`~flowtwin.physics.strand`, :mod:`~flowtwin.physics.nozzle_path`,
  :mod:`~flowtwin.physics.spline`, :mod:`~flowtwin.physics.pursuit` — strand shape and
  nozzle trajectory [004];
* :mod:`~flowtwin.physics.defaults`, :mod:`~flowtwin.physics.operating_point` — the
  documented default constants and their derivation (docs/spec.md §4).

Units are mm, s, N, MPa, MPa·s, °C; slip is a fraction (docs/spec.md §2). See docs/physics.md.
"""

__all__: list[str] = []
