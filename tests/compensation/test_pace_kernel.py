"""The pacing's compiled loops against their definitions, to the bit.

The references are the pure-Python loops the kernels replaced (the staircase's is
:func:`flowtwin.compensation.envelopes.staircase` itself), run on random pieces with the
cases the pacing meets: envelopes absent (``inf``), pieces shorter than the shortest
sub-piece, floors above the envelope, tiny E.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.compensation._pace_kernel import (
    end_bounds,
    lay_out_paced,
    staircases,
    start_bounds,
    window_max,
)
from flowtwin.compensation.envelopes import SAME, staircase

N = 400


def _pieces(seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    pr = rng.random(N) < 0.8
    nxt = np.zeros(N, dtype=bool)
    nxt[:-1] = pr[:-1] & pr[1:] & (rng.random(N - 1) < 0.9)
    cv = rng.uniform(5.0, 300.0, N)
    end_bound = np.where(rng.random(N) < 0.7, cv * rng.uniform(0.05, 1.2, N), np.inf)
    start_bound = np.where(rng.random(N) < 0.5, cv * rng.uniform(0.0, 1.2, N), np.inf)
    return {
        "pr": pr, "nxt": nxt, "cv": cv,
        "length": np.where(rng.random(N) < 0.1, rng.uniform(0.0, 0.3, N),
                           rng.uniform(0.3, 60.0, N)),
        "a": rng.uniform(0.01, 0.3, N), "k": rng.uniform(0.02, 0.3, N),
        "g": np.where(rng.random(N) < 0.9, rng.uniform(0.5, 40.0, N), 0.0),
        "acc": np.where(rng.random(N) < 0.8, rng.uniform(50.0, 5000.0, N), np.inf),
        "end_bound": end_bound, "start_bound": start_bound,
        "anchor": np.where(rng.random(N) < 0.3, cv * rng.uniform(0.1, 1.0, N), np.inf),
        "allowed": rng.random(N) < 0.9,
        "v0": np.where(rng.random(N) < 0.3, cv * rng.uniform(0.0, 1.1, N), np.inf),
        "floor": cv * rng.uniform(0.0, 0.6, N),
        "e_grid": np.where(rng.random(N) < 0.1, rng.integers(1, 6, N),
                           rng.integers(10, 5000, N)).astype(np.int64),
        "t_start": np.cumsum(rng.uniform(0.001, 0.5, N)),
    }


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_staircases_are_the_definitions(seed: int) -> None:
    p = _pieces(seed)
    pieces = np.flatnonzero(p["pr"])
    kept, counts, ends, speeds, floored = staircases(
        pieces, p["length"], p["cv"], np.array([v ** 2 for v in p["cv"][pieces].tolist()]),
        p["end_bound"], p["g"], p["start_bound"],
        np.array([v ** 2 for v in p["start_bound"][pieces].tolist()]), p["acc"], p["floor"],
        p["e_grid"], 1.15, 0.4, SAME)
    want_kept, want_counts, want_ends, want_v, want_floored = [], [], [], [], 0
    for i in pieces.tolist():
        e, v = staircase(
            float(p["length"][i]), float(p["cv"][i]), end_v_mm_s=float(p["end_bound"][i]),
            end_slope_1_s=float(p["g"][i]) if p["g"][i] > 0 else math.inf,
            start_v_mm_s=float(p["start_bound"][i]),
            start_accel_mm_s2=float(p["acc"][i]), step_ratio=1.15, min_piece_mm=0.4,
            floor_mm_s=float(p["floor"][i]))
        if all(x >= p["cv"][i] * (1.0 - SAME) for x in v):
            continue
        share = np.rint(int(p["e_grid"][i]) * np.asarray(e) / float(p["length"][i]))
        if np.any(np.diff(np.concatenate(([0.0], share))) <= 0):
            continue
        want_floored += sum(1 for x in v if x <= p["floor"][i] * (1.0 + SAME))
        want_kept.append(i)
        want_counts.append(len(e))
        want_ends.extend(e)
        want_v.extend(v)
    assert len(want_kept) > 20 and any(c > 3 for c in want_counts)  # the cases are there
    assert kept.tolist() == want_kept and counts.tolist() == want_counts
    assert ends.tolist() == want_ends and speeds.tolist() == want_v
    assert floored == want_floored


def test_the_envelope_passes_are_the_definitions() -> None:
    p = _pieces(4)
    pr, nxt, cv, length, a, k = p["pr"], p["nxt"], p["cv"], p["length"], p["a"], p["k"]
    t_start = p["t_start"]
    t_end = t_start + np.random.default_rng(5).uniform(0.0, 0.4, N)
    got_end, got_gaps = end_bounds(pr, nxt, p["anchor"], p["allowed"], p["g"], length, a, k,
                                   cv, t_start, t_end, 4.0, 0.7)
    # the backward pass as it was written in Python
    want_end = np.full(N, np.inf)
    bound, next_start, next_flow, gaps = math.inf, -1, math.inf, 0
    for i in range(N - 1, -1, -1):
        if not pr[i]:
            bound = math.inf
            continue
        b = min(bound if nxt[i] else math.inf, float(p["anchor"][i]))
        if not nxt[i] and next_start >= 0 and p["allowed"][i]:
            gap = float(t_start[next_start] - t_end[i])
            if gap < 4.0 * k[i] and math.isfinite(next_flow):
                carried = next_flow * math.exp(0.7 * max(gap, 0.0) / float(k[i])) / float(a[i])
                if carried < b and carried < cv[i]:
                    b = carried
                    gaps += 1
        want_end[i] = b
        bound = b + float(p["g"][i]) * float(length[i]) if math.isfinite(b) else math.inf
        if i == 0 or not pr[i - 1]:
            next_start = i
            next_flow = float(a[i]) * min(float(cv[i]), bound)
    assert gaps > 0 and got_gaps == gaps
    assert got_end.tobytes() == want_end.tobytes()
    got_start = start_bounds(pr, p["v0"], p["acc"], length, cv)
    want_start = np.full(N, np.inf)
    carry = math.inf
    for i in range(N):
        if not pr[i]:
            carry = math.inf
            continue
        b = min(carry, float(p["v0"][i]))
        want_start[i] = b
        if math.isfinite(b):
            end = math.sqrt(b * b + 2.0 * float(p["acc"][i]) * float(length[i]))
            carry = end if end < cv[i] else math.inf
        else:
            carry = math.inf
    assert np.isfinite(want_start).sum() > 20
    assert got_start.tobytes() == want_start.tobytes()
    got_w = window_max(a, length, nxt, 2.0)
    want_w = a.copy()
    for i in range(N):
        if nxt[i]:
            best, walked, j = a[i], length[i], i - 1
            while j >= 0 and walked < 2.0 and nxt[j]:
                best, walked, j = max(best, a[j]), walked + length[j], j - 1
            want_w[i] = best
    assert (want_w != a).any() and got_w.tobytes() == want_w.tobytes()


def test_the_paced_pieces_are_laid_out_as_defined() -> None:
    rng = np.random.default_rng(6)
    n = 50
    start = rng.uniform(-100.0, 100.0, (n, 3))
    xyz_old = start + rng.uniform(-20.0, 20.0, (n, 3))
    seg = xyz_old - start
    length = np.sqrt(np.sum(seg * seg, axis=1))
    e_old = rng.integers(50, 4000, n).astype(np.int64)
    feed_old = np.where(rng.random(n) < 0.8, rng.uniform(600.0, 18000.0, n), np.inf)
    cv = rng.uniform(10.0, 300.0, n)
    sf = rng.uniform(0.5, 2.0, n)
    kept = np.array([3, 7, 8, 20, 49], dtype=np.int64)
    counts = np.array([2, 5, 1, 3, 4], dtype=np.int64)
    ends_l, v_l = [], []
    for i, c in zip(kept.tolist(), counts.tolist(), strict=True):
        cut = np.sort(rng.uniform(0.0, length[i], c - 1))
        ends_l.extend([*cut.tolist(), float(length[i])])
        v_l.extend((cv[i] * rng.choice([0.3, 0.7, 1.0], c)).tolist())
    ends, speeds = np.array(ends_l), np.array(v_l)
    new_counts = np.ones(n, dtype=np.int64)
    new_counts[kept] = counts
    piece = np.repeat(np.arange(n), new_counts)
    offsets = np.concatenate(([0], np.cumsum(new_counts)))
    got = (xyz_old[piece].copy(), e_old[piece].copy(), feed_old[piece].copy())
    lay_out_paced(kept, counts, ends, speeds, offsets, length, start, seg, xyz_old, e_old,
                  feed_old, cv, sf, SAME, *got)
    # the layout as it was written with numpy
    xyz, e, feed = xyz_old[piece].copy(), e_old[piece].copy(), feed_old[piece].copy()
    at = 0
    for i, c in zip(kept.tolist(), counts.tolist(), strict=True):
        o = int(offsets[i])
        frac = ends[at:at + c] / length[i]
        frac[-1] = 1.0
        xyz[o:o + c] = start[i] + frac[:, None] * seg[i]
        xyz[o + c - 1] = xyz_old[i]
        total = int(e_old[i])
        cum = np.rint(total * frac).astype(np.int64)
        cum[-1] = total
        e[o:o + c] = np.diff(np.concatenate(([0], cum)))
        old = float(feed_old[i])
        for jj, v in enumerate(speeds[at:at + c].tolist()):
            if v >= cv[i] * (1.0 - SAME):
                continue
            f = math.floor(60e3 * v / float(sf[i])) / 1e3
            feed[o + jj] = min(f, old) if math.isfinite(old) else f
        at += c
    for g_, w_ in zip(got, (xyz, e, feed), strict=True):
        assert g_.tobytes() == w_.tobytes()
    for i, c in zip(kept.tolist(), counts.tolist(), strict=True):  # each piece's E kept
        assert int(np.sum(got[1][offsets[i]:offsets[i] + c])) == int(e_old[i])
