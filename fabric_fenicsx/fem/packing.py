"""The coefficients of a compiled form, packed by one gather instead of DOLFINx's packing.

Before every assembly DOLFINx 0.5.2 packs each cell's coefficient values (the displacement, the
yarn stresses, the live-cell mask, ...) into one array per integral (``pack_coefficients``):
per step as long as the assembly itself on the impact meshes. For the elements the membrane's
terms use (Lagrange, DG and quadrature spaces, no dof transformations) the packed array is a
fixed selection of the coefficient Functions' values, so it can be taken by a single
gather from their current arrays. :class:`CoefficientPacker` finds that selection once by
packing distinct probe values, checks it against DOLFINx's own packing of the real values, and
falls back to DOLFINx's packing if they differ (an element with transformations, say).
Assembly stays DOLFINx's: ``assemble_vector(b, form, coeffs=packer.pack())``.

The membrane's forms pack one gathered coefficient (the displacement: 12 values of a
quadrilateral's nodes) and coefficients of one value per cell in cell order (the stresses, the
live-cell mask), each a column of the packed array: those are packed by one compiled pass
straight from the Functions' arrays. Other layouts copy the arrays into one source and gather
it by ``numpy.take`` (two passes over the values instead of one).
"""
from __future__ import annotations

import numpy as np
from dolfinx.cpp.fem import pack_coefficients
from numba import njit

__all__ = ["CoefficientPacker"]


class CoefficientPacker:
    """Packs the coefficients of ``form`` (a compiled ``dolfinx.fem.form``) by a gather.

    :meth:`pack` returns what ``dolfinx.cpp.fem.pack_coefficients(form)`` returns for the
    Functions' current values (the same arrays, bit for bit: checked at construction);
    :attr:`gathers` is False where the check failed and DOLFINx packs instead.
    """

    def __init__(self, form):
        self.form = form
        self._arrays = [c.x.array for c in form.coefficients]
        sizes = [a.size for a in self._arrays]
        self._offsets = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
        self._source = np.empty(int(self._offsets[-1]))
        self._index: dict = {}
        self._packed: dict = {}
        self._columns: dict = {}
        self.gathers = False
        if not self._arrays:
            return
        saved = [a.copy() for a in self._arrays]
        try:
            for a, start in zip(self._arrays, self._offsets[:-1]):
                a[:] = start + np.arange(a.size, dtype=float)   # exact integers up to 2^53
            probe = pack_coefficients(form)
            for key, values in probe.items():
                index = np.rint(values).astype(np.int64)
                if not (np.array_equal(index, values) and index.size and index.min() >= 0
                        and index.max() < self._source.size):
                    return
                self._index[key] = index
                self._packed[key] = np.empty_like(values)
            self._columns = _one_gather_and_columns(self._index, self._offsets, self._arrays)
            # the selection must also hold for arbitrary values (no transformation, no sign)
            rng = np.random.default_rng(0)
            for a in self._arrays:
                a[:] = rng.standard_normal(a.size)
            reference = pack_coefficients(form)
            self.gathers = True
            mine = self.pack()
            self.gathers = (mine.keys() == reference.keys()
                            and all(np.array_equal(mine[k], reference[k]) for k in reference))
        finally:
            for a, s in zip(self._arrays, saved):
                a[:] = s

    def pack(self) -> dict:
        """The packed coefficients of the form's Functions as they are now."""
        if not self.gathers:
            return pack_coefficients(self.form)
        if self._columns:
            for key, (a, index, first, copied, columns) in self._columns.items():
                _pack_columns(a, index, first, copied, columns, self._packed[key])
            return self._packed
        source = self._source
        for a, start, stop in zip(self._arrays, self._offsets[:-1], self._offsets[1:]):
            source[start:stop] = a
        for key, index in self._index.items():
            # the index was checked to lie in range at construction: mode "clip" only skips
            # the bounds check and the buffered copy that mode "raise" makes with ``out``
            np.take(source, index, out=self._packed[key], mode="clip")
        return self._packed


def _one_gather_and_columns(indices: dict, offsets: np.ndarray, arrays: list) -> dict:
    """For each key of ``indices`` (a packed array's index into ``arrays`` laid end to end at
    ``offsets``): (the array read by a block of adjacent columns, its local index, the block's
    first column, the tuple of the arrays read by one column each in cell order, those
    columns). {} where a key's packed array has another layout (then the packer copies and
    takes), or an array is not a 1-D float64 one."""
    if any(a.dtype != np.float64 or a.ndim != 1 for a in arrays):
        return {}
    plans: dict = {}
    for key, index in indices.items():
        if index.ndim != 2 or index.shape[0] == 0:
            return {}
        owner = np.searchsorted(offsets, index, side="right") - 1
        if not np.all(owner == owner[:1]):       # every column reads one array
            return {}
        owner, rows = owner[0], np.arange(index.shape[0])
        gathered, copied, columns = [], [], []
        for j in np.unique(owner):
            cols = np.flatnonzero(owner == j)
            local = index[:, cols] - offsets[j]
            if cols.size == 1 and np.array_equal(local[:, 0], rows) and arrays[j].size == rows.size:
                copied.append(arrays[j])
                columns.append(cols[0])
            elif cols[-1] - cols[0] + 1 == cols.size and local.max() < 2**32:
                gathered.append((arrays[j], local.astype(np.uint32), int(cols[0])))
            else:
                return {}
        if len(gathered) != 1 or not copied:
            return {}
        plans[key] = (*gathered[0], tuple(copied), np.array(columns, dtype=np.int64))
    return plans


@njit(cache=True, nogil=True)
def _pack_columns(a, index, first, copied, columns, out):
    """out[c, first + k] = a[index[c, k]] and out[c, columns[j]] = copied[j][c] for every row
    c: the packed coefficients from the arrays themselves (index unsigned: no wraparound test)."""
    width = index.shape[1]
    for c in range(index.shape[0]):
        for k in range(width):
            out[c, first + k] = a[index[c, k]]
    for j in range(len(copied)):
        b = copied[j]
        column = columns[j]
        for c in range(b.size):
            out[c, column] = b[c]
