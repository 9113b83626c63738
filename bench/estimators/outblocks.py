"""Zeroed NAV_SOLUTION / NAV_QUALITY records for a compiled step to fill, taken from
blocks allocated ahead (one allocation per ``block`` epochs instead of two per step)."""

from __future__ import annotations

import numpy as np

from bench.dut import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE

__all__ = ["OutputBlocks"]


class OutputBlocks:
    """``take(n)``: the next ``n`` unused rows of two blocks allocated together. No two
    calls share a row, so what a step returns are views of its own rows, as zeroed as
    arrays of their own."""

    def __init__(self, block: int = 4096):
        self.block = block
        self._sol = np.zeros(0, NAV_SOLUTION_DTYPE)
        self._qual = np.zeros(0, NAV_QUALITY_DTYPE)
        self._at = 0

    def take(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        a = self._at
        if a + n > len(self._sol):
            m = max(n, self.block)
            self._sol, self._qual = np.zeros(m, NAV_SOLUTION_DTYPE), np.zeros(m, NAV_QUALITY_DTYPE)
            a = 0
        self._at = a + n
        return self._sol[a : a + n], self._qual[a : a + n]
