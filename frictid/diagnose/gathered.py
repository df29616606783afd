"""Columns read from a table of the samples' distinct positions, never formed over every sample.

An encoder's positions repeat (208 000 distinct among 1.16 M sliding samples on the one-hour bench log), so
a column that is a function of the position alone (the position torque's sin and cos of a period, its
smooth form ``1, d, d^2``) takes one value per distinct position: the table. A :class:`Gathered` column is
the table and each sample's row in it; it is read where it is used, block by block into the buffer of the
streamed sums of products (:meth:`fill`, :meth:`frictid.diagnose.model.Context.fold_products`) and at the
samples of a prediction (:meth:`at`). Each value is the table's, the value the whole column would hold at
that sample, so every sum and prediction is the same number; what is saved is the whole column (9 MB of
fresh memory per column on the one-hour log, two to three per setting, five settings per fold and step) and
its copy into the block buffer.
"""
from __future__ import annotations

import numpy as np


class Gathered:
    """A column ``table[index]`` (``index``: each sample's row in ``table``, in range), read block by block."""

    __slots__ = ("table", "index")

    def __init__(self, table: np.ndarray, index: np.ndarray):
        self.table = table
        self.index = index

    @property
    def size(self) -> int:
        return int(self.index.size)

    def at(self, rows=None) -> np.ndarray:
        """The column at samples ``rows`` (a slice, an index array, or None for every sample), a new array."""
        ix = self.index if rows is None else self.index[rows]
        # mode "wrap": the indices are in range, and the default "raise" copies out through a buffer
        return np.take(self.table, ix, mode="wrap")

    def __getitem__(self, rows) -> np.ndarray:
        return self.at(rows)

    def fill(self, out: np.ndarray, s: int, e: int) -> np.ndarray:
        """Samples ``s:e`` of the column written into ``out`` (no temporary)."""
        return np.take(self.table, self.index[s:e], out=out, mode="wrap")
