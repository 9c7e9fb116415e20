"""Tension-field relaxation of the yarn strains: a yarn that cannot carry compression wrinkles.

The unit cell gives a compressed yarn a compressive force P_j < 0 (an elastica in bending,
Eq. 2-31) while the crossing yarn i is stretched. The membrane has no bending stiffness, so it
carries no compression, and a yarn pushed below its force-free length wrinkles. Cutting P_j to
zero while P_i is still read at the apparent strain E_j is not a material law: P_i depends on
E_j through the contact (crimp interchange) but P_j no longer depends on E_i, so the stresses
are no gradient and a strain cycle through that band gives out work (measured: about -16 J/m^2
around a 0.004 x 0.004 square at E1 = 0.026, E2 = -0.022; the Y0 scene at 20 m/s gave 0.9 J
back over one rebound, docs/impact_model.md).

Tension-field theory (Pipkin's relaxed energy of a wrinkled membrane) instead takes the yarn at
the strain it wrinkles to: W_rel(E_i, E_j) = W(E_i, max(E_j, E_j*(E_i))), E_j* the strain where
P_j(E_i, E_j*) = 0. Its stresses are P_i(E_i, E_j*) and P_j = 0: a gradient field (dW/dE_j
vanishes at E_j*), so the work of a closed strain cycle is zero again. :func:`relaxed_strains`
returns the strains (E_i, E_j*) at which the unit cell is to be asked.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fabric_fenicsx.surrogate.kernels.interp import ROOT_FOUND, ROOT_NONE

__all__ = ["relaxed_strains", "RelaxStats"]


@dataclass
class RelaxStats:
    """Counts over a run: point evaluations relaxed, and those left unrelaxed because P_j
    stayed compressive up to the table's top (no force-free length: none expected)."""
    relaxed: int = 0
    no_root: int = 0


def relaxed_strains(surrogate, E1, E2, a1, a2, stats: RelaxStats | None = None, guess=None):
    """(E1r, E2r): the strains of a tension field (module docstring), vectorised.

    surrogate: its signed ``lookup`` and ``zero_force_strain``
    (:class:`fabric_fenicsx.surrogate.table.Surrogate`) and ``E_table``; E1, E2 inside the
    table; a1, a2: the frozen damage. A yarn j is relaxed where it is compressed (E_j < 0) with
    P_j < 0 while the crossing yarn is stretched (E_i > 0): its strain becomes the root E_j* of
    P_j(E_i, .), searched in (E_j, 0] (the force-free length is near the rest length) and, where
    P_j(E_i, 0) < 0 still, in (0, E_hi]. Elsewhere the strains are returned unchanged (the slack
    rules of :mod:`fabric_fenicsx.fem.yarn_stress` apply there). ``guess``: (G1, G2) like E1,
    E2, where the searches start if inside their bracket (the last step's relaxed strains)."""
    E = [np.array(E1, dtype=float, copy=True), np.array(E2, dtype=float, copy=True)]
    for j in (0, 1):
        i = 1 - j
        k = np.flatnonzero((E[j] < 0.0) & (E[i] > 0.0))
        if k.size == 0:
            continue
        root, status = surrogate.zero_force_strain(j + 1, E[i][k], E[j][k], np.zeros(k.size),
                                                   a1[k], a2[k],
                                                   None if guess is None else guess[j][k])
        far = np.flatnonzero(status == ROOT_NONE)   # still compressive at the rest length
        if far.size:
            kf = k[far]
            root[far], status[far] = surrogate.zero_force_strain(
                j + 1, E[i][kf], np.zeros(kf.size), np.full(kf.size, surrogate.E_table[1]),
                a1[kf], a2[kf])
            root[far[status[far] == ROOT_NONE]] = E[j][kf[status[far] == ROOT_NONE]]
        E[j][k] = root
        if stats is not None:
            stats.relaxed += int(np.count_nonzero(status == ROOT_FOUND))
            stats.no_root += int(np.count_nonzero(status == ROOT_NONE))
    return E[0], E[1]
