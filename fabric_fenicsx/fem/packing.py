"""The coefficients of a compiled form, packed by one gather instead of DOLFINx's packing.

Before every assembly DOLFINx 0.5.2 packs each cell's coefficient values (the displacement, the
yarn stresses, the live-cell mask, ...) into one array per integral (``pack_coefficients``):
per step as long as the assembly itself on the impact meshes. For the elements the membrane's
terms use (Lagrange, DG and quadrature spaces, no dof transformations) the packed array is a
fixed selection of the coefficient Functions' values, so it can be taken by a single
``numpy.take`` from their current arrays. :class:`CoefficientPacker` finds that selection once
by packing distinct probe values, checks it against DOLFINx's own packing of the real values,
and falls back to DOLFINx's packing if they differ (an element with transformations, say).
Assembly stays DOLFINx's: ``assemble_vector(b, form, coeffs=packer.pack())``.
"""
from __future__ import annotations

import numpy as np
from dolfinx.cpp.fem import pack_coefficients

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
        source = self._source
        for a, start, stop in zip(self._arrays, self._offsets[:-1], self._offsets[1:]):
            source[start:stop] = a
        for key, index in self._index.items():
            # the index was checked to lie in range at construction: mode "clip" only skips
            # the bounds check and the buffered copy that mode "raise" makes with ``out``
            np.take(source, index, out=self._packed[key], mode="clip")
        return self._packed
