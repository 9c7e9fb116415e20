"""A failure rule that sees along the yarns: the damage of each yarn family is driven by its
strain averaged along that yarn over a length of the fabric, not by the cell's own strain.

The thesis's rule (Eq. 2-25) gives each quadrature point the damage alpha_i(mu_i) of its own
strains: a softening law without a length, so that a tear localises in one row of cells and
follows the rows (docs/mesh_independence.md; the tear test, :mod:`fabric_fenicsx.studies.tear`).
Here yarn i's damage at a cell is alpha_i(mu_i) of the unit cell at the *driving strains*

    Ebar_i(c) = sum_k w_ck E_i(k) / sum_k w_ck,

the average of yarn i's strain over the live cells k whose centres lie on the yarn through c:
within ``length / 2`` of c along the yarn and within half of c's own width across it (a band
one cell wide, so that neighbouring yarns stay independent and a tear can cut between them),
weighted by the cells' areas. The stresses stay those of each cell's own strains, at that
damage (a nonlocal damage model in the sense of Pijaudier-Cabot and Bazant, J. Eng. Mech. 113
(1987) 1512-1533, with the averaging restricted to the yarn). With ``length`` below the cells'
size every cell averages only itself: the thesis's rule.

One point per cell (the reduced element) and one rank: the neighbourhood of a cell near a
partition boundary would need the other rank's strains, which this prototype does not
exchange; it refuses both with a message.
"""
from __future__ import annotations

import numpy as np

__all__ = ["yarn_neighbourhoods", "YarnAverage"]


def yarn_neighbourhoods(centres: np.ndarray, areas: np.ndarray, directions, length: float, width: float = 0.0):
    """The averaging operators (scipy.sparse CSR, n x n, unnormalised weights = areas) of the
    cells with reference centres ``centres`` (n, 2) and areas ``areas`` (n,), one per yarn
    direction of ``directions`` (unit 2-vectors): row c holds the cells k with
    |(x_k - x_c) . d| <= length / 2 and |(x_k - x_c) . d_perp| <= max(sqrt(area_c), width) / 2
    (``width`` 0: one cell across the yarn; ``width = length``: a square window)."""
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree

    centres = np.asarray(centres, float)
    areas = np.asarray(areas, float)
    width = np.maximum(np.sqrt(areas), width)
    tree = cKDTree(centres)
    reach = np.hypot(0.5 * length, 0.5 * width)
    rows = tree.query_ball_point(centres, reach)
    counts = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
    i = np.repeat(np.arange(len(rows)), counts)
    k = np.concatenate([np.asarray(r, dtype=np.int64) for r in rows]) if len(rows) else np.zeros(0, np.int64)
    d = centres[k] - centres[i]
    out = []
    for direction in directions:
        t = np.asarray(direction, float)
        n = np.array([-t[1], t[0]])
        keep = (np.abs(d @ t) <= 0.5 * length) & (np.abs(d @ n) <= 0.5 * width[i])
        out.append(csr_matrix((areas[k[keep]], (i[keep], k[keep])), shape=(len(rows), len(rows))))
    return out


class YarnAverage:
    """The driving strains of :mod:`this rule <fabric_fenicsx.fem.yarn_average>` for a
    :class:`~fabric_fenicsx.fem.yarn_stress.YarnStress` (its ``damage_drive``).

    centres, areas: the owned cells' reference centres (n, 2) and areas (n,); directions: the
    warp and fill directions (unit 2-vectors, the material angle); length: the averaging length
    along the yarns (m); width: across them (m; 0: one cell)."""

    def __init__(self, centres, areas, directions, length: float, comm=None, width: float = 0.0):
        if comm is not None and comm.size > 1:
            raise ValueError("the yarn-average failure rule runs on one rank only (its neighbourhoods do not "
                             "cross partitions); run without mpirun")
        if not length > 0:
            raise ValueError(f"yarn-average length = {length!r}: must be > 0 m")
        self.length = float(length)
        self.W = yarn_neighbourhoods(centres, areas, directions, self.length, width)

    def __call__(self, E1: np.ndarray, E2: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Ebar1, Ebar2) at every cell from the yarn strains (E1, E2) of every cell, averaged
        over the live cells only (a removed cell carries no yarn); a cell with no live
        neighbour keeps its own strain."""
        w = live.astype(float)
        out = []
        for W, E in zip(self.W, (E1, E2)):
            num, den = W @ (w * E), W @ w
            out.append(np.divide(num, den, out=np.array(E, dtype=float), where=den > 0))
        return out[0], out[1]
