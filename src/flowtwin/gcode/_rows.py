"""Growable output buffers of the scanning kernel for one read."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flowtwin.gcode.moves import MOVE_DTYPE

__all__ = ["_Rows"]


@dataclass
class _Rows:
    """Growable output buffers of the kernel for one chunk."""

    moves: np.ndarray
    other: np.ndarray
    n: int = 0
    n_other: int = 0

    evals: np.ndarray = field(default_factory=lambda: np.empty((0, 27)))

    @classmethod
    def make(cls, cap: int, cap_other: int) -> _Rows:
        return cls(np.empty(cap, MOVE_DTYPE), np.empty((cap_other, 6), np.int64),
                   evals=np.zeros((cap_other, 27)))

    def grow_moves(self, need: int) -> None:
        cap = max(self.moves.shape[0] + self.moves.shape[0] // 4, self.n + need + 16)
        new = np.empty(cap, MOVE_DTYPE)
        new[: self.n] = self.moves[: self.n]
        self.moves = new

    def grow_other(self) -> None:
        cap = 2 * self.other.shape[0] + 16
        new = np.empty((cap, 6), np.int64)
        new[: self.n_other] = self.other[: self.n_other]
        self.other = new
        vals = np.zeros((cap, 27))
        vals[: self.n_other] = self.evals[: self.n_other]
        self.evals = vals

    def add(self, line: int, tool: int, xyz: tuple[float, float, float], de: float,
            feed: float, flow: float, kind: int) -> None:
        if self.n >= self.moves.shape[0]:
            self.grow_moves(1)
        row = self.moves[self.n]
        row["x"], row["y"], row["z"] = xyz
        row["de"] = de
        row["feed_mm_s"] = feed
        row["line"] = line
        row["tool"] = tool
        row["kind"] = kind
        row["flow"] = flow
        self.n += 1
