"""Per-row columns filled after the scan (numba): the feature and layer of each move.

Both are known only once Python has read the chunk's comments, so they are filled in one
pass over the chunk's rows (the table is much larger than the cache: one pass, not two).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.gcode._arc import K_EXTRUDE

__all__ = ["fill_columns"]


@njit(cache=True, nogil=True)
def _fill(moves, f_ks, f_vals, feature, l_ks, l_vals, layer, by_markers, max_z, rises_z):  # type: ignore[no-untyped-def]
    n = moves.shape[0]
    jf = 0
    jl = 0
    n_rises = 0
    for r in range(n):
        # a change takes effect at row k once every earlier change has (running maximum)
        while jf < f_ks.shape[0] and f_ks[jf] <= r:
            feature = f_vals[jf]
            jf += 1
        row = moves[r]
        row.feature = feature
        if by_markers:
            while jl < l_ks.shape[0] and l_ks[jl] <= r:
                layer = l_vals[jl]
                jl += 1
        else:
            # no slicer markers: a new layer starts at the first extrusion above the last
            z = row.z if row.kind & K_EXTRUDE else -np.inf
            new = max(max_z, z)
            if new > max_z + 1e-6:
                layer += 1
                rises_z[n_rises] = new
                n_rises += 1
            max_z = new
        row.layer = layer
    if f_ks.shape[0]:
        feature = f_vals[-1]
    if by_markers and l_ks.shape[0]:
        layer = l_vals[-1]
    return feature, layer, max_z, n_rises


def fill_columns(moves: npt.NDArray[np.void], feature_changes: list[tuple[int, int]],
                 layer_changes: list[tuple[int, int, float]] | None, *, base: int,
                 feature: int, layer: int, max_extrude_z: float,
                 ) -> tuple[int, int, float, list[float]]:
    """Fill ``moves["feature"]`` and ``moves["layer"]`` of one chunk, in place.

    Parameters
    ----------
    moves
        The chunk's rows (:data:`MOVE_DTYPE`), shape ``(n,)``.
    feature_changes
        ``(move_index, feature_id)`` in file order; a change takes effect at row
        ``move_index - base``.
    layer_changes
        ``(move_index, line, z)`` of the slicer's layer markers, or ``None`` when the file
        has none: a layer then starts at each extrusion more than 1 µm above every
        earlier one.
    base
        Move index of the chunk's first row.
    feature, layer, max_extrude_z
        Feature, layer and highest extrusion Z (mm) in force before the chunk.

    Returns
    -------
    feature, layer, max_extrude_z, new_layer_z
        The state after the chunk and, without markers, the Z (mm) of each new layer.
    """
    f_ks = np.array([mi for mi, _ in feature_changes], dtype=np.int64) - base
    f_vals = np.array([fid for _, fid in feature_changes], dtype=np.int64)
    by_markers = layer_changes is not None
    markers = layer_changes or []
    l_ks = np.array([mi for mi, _line, _z in markers], dtype=np.int64) - base
    l_vals = layer + 1 + np.arange(len(markers), dtype=np.int64)
    rises_z = np.empty(0 if by_markers else moves.shape[0])
    feature, layer, max_z, n_rises = _fill(moves, f_ks, f_vals, feature, l_ks, l_vals, layer,
                                           by_markers, max_extrude_z, rises_z)
    return int(feature), int(layer), float(max_z), rises_z[:n_rises].tolist()
