"""Growable output buffers of the scanning kernel for one read."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowtwin.gcode import _kernel as kernel
from flowtwin.gcode.moves import MOVE_DTYPE

__all__ = ["_Rows"]


@dataclass
class _Rows:
    """Growable output buffers of the kernel for one chunk.

    ``moves`` holds the move rows, ``other`` the lines left to Python (see
    :func:`flowtwin.gcode._kernel.scan`) and ``vals`` the packed values of their words.
    """

    moves: np.ndarray
    other: np.ndarray
    vals: np.ndarray
    n: int = 0
    n_other: int = 0
    n_vals: int = 0

    @classmethod
    def make(cls, cap: int, cap_other: int) -> _Rows:
        return cls(np.empty(cap, MOVE_DTYPE), np.empty((cap_other, kernel.N_OTHER_COLS), np.int64),
                   np.empty(2 * cap_other + kernel.MAX_WORDS))

    def grow_moves(self, need: int) -> None:
        cap = max(self.moves.shape[0] + self.moves.shape[0] // 4, self.n + need + 16)
        new = np.empty(cap, MOVE_DTYPE)
        new[: self.n] = self.moves[: self.n]
        self.moves = new

    def grow_other(self) -> None:
        if self.n_other + 1 > self.other.shape[0]:
            cap = 2 * self.other.shape[0] + 16
            new = np.empty((cap, kernel.N_OTHER_COLS), np.int64)
            new[: self.n_other] = self.other[: self.n_other]
            self.other = new
        if self.n_vals + kernel.MAX_WORDS > self.vals.shape[0]:
            vals = np.empty(2 * self.vals.shape[0] + kernel.MAX_WORDS)
            vals[: self.n_vals] = self.vals[: self.n_vals]
            self.vals = vals

    def add(self, line: int, tool: int, xyz: tuple[float, float, float], de: float,
            feed: float, flow: float, kind: int, e_acc: np.ndarray) -> None:
        """Append a row made in Python; ``e_acc`` is the kernel's running E per tool."""
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
        t = (tool + 32768) % 65536
        e_acc[t] += row["de"]  # the stored float64, summed as the kernel does
        row["e"] = e_acc[t]
        self.n += 1
