"""The chain's products ``C·x`` and ``Cᵀ·y`` taken straight from its arrays
(``Chain.matvec``, ``Chain.rmatvec``) equal those of the assembled matrix
(``Chain.matrix()``) to the bit: on random chains, edge cases and a real print's
refinements."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.program import Chain


def _assert_same(chain: Chain, x: np.ndarray, y: np.ndarray) -> None:
    c = chain.matrix()
    assert chain.matvec(x).tobytes() == c.matvec(x).tobytes()
    assert chain.rmatvec(y).tobytes() == c.rmatvec(y, chain.size).tobytes()


def _chain(alpha: list[float], e_p: list[float], b_p: list[float], pre: list[int]) -> Chain:
    return Chain.of(np.array(alpha, dtype=np.float64), np.array(e_p, dtype=np.float64),
                    np.array(b_p, dtype=np.float64), np.array(pre, dtype=np.int64))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_chains(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 200
    alpha = rng.uniform(0.2, 1.0, n)
    alpha[rng.choice(n, 30, replace=False)] = 0.0
    e_p = rng.uniform(0.5, 1.0, n)
    e_p[rng.choice(n, 10, replace=False)] = 0.0  # −0.0 entries (no entry of C)
    pre = np.sort(rng.choice(np.flatnonzero(alpha == 0.0), 12, replace=False))
    chain = Chain.of(alpha, e_p, rng.uniform(0.01, 3.0, n), pre)
    x = rng.normal(size=chain.size)
    x[rng.choice(chain.size, 20, replace=False)] = -0.0
    y = rng.normal(size=n)
    y[rng.choice(n, 20, replace=False)] = 0.0
    _assert_same(chain, x, y)


def test_edge_cases() -> None:
    empty = _chain([], [], [], [])
    _assert_same(empty, np.zeros(0), np.zeros(0))
    one = _chain([0.0], [1.0], [2.0], [0])  # one piece, pre-charged
    _assert_same(one, np.array([1.5, -2.0]), np.array([-0.5]))
    # a pre-charge on the first and the last piece, a piece whose E is zero
    ch = _chain([0.0, 0.5, 0.0, 0.7], [1.0, 0.0, 0.8, 0.9], [1.0, 0.5, 2.0, 1e-12], [0, 2])
    _assert_same(ch, np.array([1.0, -1.0, 3.0, 1e6, 0.25, -0.0]),
                 np.array([0.0, -0.0, 2.0, -3.0]))
    # no pre-charge, negative zeros in x and y
    ch = _chain([0.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [])
    _assert_same(ch, np.array([-0.0, -0.0, -0.0]), np.array([-0.0, 0.0, -0.0]))


@pytest.mark.corpus
def test_the_refinements_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    sizes: list[int] = []
    own_matvec, own_rmatvec = Chain.matvec, Chain.rmatvec

    def matvec(self: Chain, x: Any) -> Any:
        out = own_matvec(self, x)
        assert out.tobytes() == self.matrix().matvec(x).tobytes()
        sizes.append(self.n)
        return out

    def rmatvec(self: Chain, y: Any) -> Any:
        out = own_rmatvec(self, y)
        assert out.tobytes() == self.matrix().rmatvec(y, self.size).tobytes()
        sizes.append(self.n)
        return out

    monkeypatch.setattr(Chain, "matvec", matvec)
    monkeypatch.setattr(Chain, "rmatvec", rmatvec)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert len(sizes) >= 8 and max(sizes) > 1000
