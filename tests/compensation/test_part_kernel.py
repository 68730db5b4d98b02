"""One part of the refinement's program assembled in one compiled pass
(``flowtwin.compensation._part_kernel``) against the chain's slot tables stacked and
compacted with numpy as ``PartProgram.solve`` did before: the same arrays to the bit,
on random chains, edge cases and a real print's refinements."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import _part_kernel, compensate
from flowtwin.compensation._part_kernel import part_hessian, part_rows
from flowtwin.compensation.program import Chain, stack_rows


def _chain_of(diag: Any, sub: Any, pre: Any, pre_of: Any, ni: Any) -> Chain:
    k_y = int(np.count_nonzero(pre_of >= 0))
    pre_piece = np.zeros(k_y, dtype=np.int64)
    has = np.flatnonzero(pre_of >= 0)
    pre_piece[pre_of[has]] = has
    return Chain(diag, sub, pre, pre_of, pre_piece, ni)


def _numpy_rows(diag: Any, sub: Any, pre: Any, pre_of: Any, ni: Any, c0: Any, c_min: Any,
                c_hi: Any, y_hi: Any, use_jump: bool, stepped: Any, jump: Any, capped: Any,
                state_max: Any) -> tuple[Any, ...]:
    ch = _chain_of(diag, sub, pre, pre_of, ni)
    n, k_y = ch.n, y_hi.size
    con = [ch.box_rows(), ch.unit_rows(n + np.arange(k_y))]
    d_con = [c0, np.zeros(k_y)]
    lo_con = [c_min, np.zeros(k_y)]
    hi_con = [c_hi, y_hi]
    pull = np.flatnonzero(c_min < 0)
    if pull.size:
        con.append(ch.unit_rows(pull))
        d_con.append(np.zeros(pull.size))
        lo_con.append(np.zeros(pull.size))
        hi_con.append(np.full(pull.size, np.inf))
    if use_jump:
        step = np.flatnonzero(stepped)
        if step.size:
            j = np.maximum(jump[step], 1e-9)
            con.append(ch.step_rows(step))
            d_con.append(c0[step] - c0[step - 1])
            lo_con.append(-j)
            hi_con.append(j)
    if capped.size:
        con.append(ch.unit_rows(np.flatnonzero(capped)))
        limit = state_max[capped]
        d_con.append(np.zeros(limit.size))
        lo_con.append(np.full(limit.size, -np.inf))
        hi_con.append(limit)
    rows = stack_rows(con)
    return (rows.ptr, rows.col, rows.val, np.concatenate(d_con), np.concatenate(lo_con),
            np.concatenate(hi_con))


def _numpy_hessian(diag: Any, sub: Any, pre: Any, pre_of: Any, pre_piece: Any, ni: Any,
                   v: Any, v_y: Any, inv_scale: float) -> tuple[Any, ...]:
    ch = Chain(diag, sub, pre, pre_of, pre_piece, ni)
    h_upper, _ = ch.hessian(v, v_y)
    h_val = h_upper.val * inv_scale
    keep = h_val != 0.0
    return (np.repeat(np.arange(ch.size), np.diff(h_upper.ptr))[keep], h_upper.col[keep],
            h_val[keep])


def _same(got: tuple[Any, ...], want: tuple[Any, ...]) -> None:
    assert len(got) == len(want)
    for k, (a, b) in enumerate(zip(got, want, strict=True)):
        assert a.dtype == b.dtype, k
        assert a.tobytes() == b.tobytes(), k


def _check(ch: Chain, rng: np.random.Generator, *, use_jump: bool, cap: bool) -> None:
    n, k_y = ch.n, ch.pre_piece.size
    c0 = rng.normal(size=n)
    c_min = rng.normal(size=n)
    c_hi = np.where(rng.random(n) < 0.2, np.inf, c_min + rng.random(n))
    y_hi = rng.uniform(0.5, 3.0, k_y)
    stepped = rng.random(n) < 0.6
    stepped[:1] = False
    jump = np.where(rng.random(n) < 0.3, 1e-12, rng.random(n))
    jump[rng.random(n) < 0.1] = np.nan
    capped = rng.random(n) < 0.5 if cap else np.zeros(0, dtype=bool)
    state_max = rng.uniform(0.0, 5.0, n) if cap else np.zeros(0)
    args = (ch.diag, ch.sub, ch.pre, ch.pre_of, ch.new_index, c0, c_min, c_hi, y_hi,
            use_jump, stepped, jump, capped, state_max)
    _same(part_rows(*args), _numpy_rows(*args))
    v = rng.uniform(0.0, 2.0, n)
    v[rng.random(n) < 0.1] = 0.0
    h_args = (ch.diag, ch.sub, ch.pre, ch.pre_of, ch.pre_piece, ch.new_index, v,
              rng.uniform(0.1, 2.0, k_y), 1.0 / rng.uniform(0.5, 1e3))
    _same(part_hessian(*h_args), _numpy_hessian(*h_args))


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize(("use_jump", "cap"), [(False, False), (True, False), (True, True)])
def test_random_parts(seed: int, use_jump: bool, cap: bool) -> None:
    rng = np.random.default_rng(seed)
    n = 150
    alpha = rng.uniform(0.2, 1.0, n)
    alpha[rng.choice(n, 25, replace=False)] = 0.0
    alpha[0] = 0.0
    e_p = rng.uniform(0.5, 1.0, n)
    e_p[rng.choice(n, 8, replace=False)] = 0.0  # −0.0 entries (no entry)
    pre = np.sort(rng.choice(np.flatnonzero(alpha == 0.0), 10, replace=False))
    ch = Chain.of(alpha, e_p, rng.uniform(0.01, 3.0, n), pre)
    _check(ch, rng, use_jump=use_jump, cap=cap)


def test_edge_cases() -> None:
    rng = np.random.default_rng(7)
    one = Chain.of(np.zeros(1), np.ones(1), np.full(1, 2.0), np.zeros(0, dtype=np.int64))
    pre_one = Chain.of(np.zeros(1), np.ones(1), np.full(1, 2.0), np.zeros(1, dtype=np.int64))
    # pre-charges on the first and the last piece, a piece of zero E, tiny B
    ch = Chain.of(np.array([0.0, 0.5, 0.0, 0.7, 0.0]), np.array([1.0, 0.0, 0.8, 0.9, 1.0]),
                  np.array([1.0, 0.5, 2.0, 1e-12, 1e300]), np.array([0, 2, 4]))
    for c in (one, pre_one, ch):
        for use_jump, cap in ((False, False), (True, True)):
            _check(c, rng, use_jump=use_jump, cap=cap)
    # a scale that makes products underflow to zero (dropped)
    h_args = (ch.diag, ch.sub, ch.pre, ch.pre_of, ch.pre_piece, ch.new_index,
              np.array([1.0, 1e-300, 1.0, 1.0, 1.0]), np.ones(3), 1e-300)
    _same(part_hessian(*h_args), _numpy_hessian(*h_args))


@pytest.mark.corpus
def test_the_parts_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    sizes: list[int] = []
    rows_kernel, hessian_kernel = part_rows, part_hessian

    def rows(*args: Any) -> Any:
        out = rows_kernel(*args)
        _same(out, _numpy_rows(*args))
        sizes.append(int(args[0].size))
        return out

    def hessian(*args: Any) -> Any:
        out = hessian_kernel(*args)
        _same(out, _numpy_hessian(*args))
        return out

    monkeypatch.setattr(_part_kernel, "part_rows", rows)
    monkeypatch.setattr(_part_kernel, "part_hessian", hessian)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert len(sizes) >= 2 and max(sizes) > 1000
