"""The yarn crack with a tip that reads its yarn: a crack's tip runs on when the yarn it would cut
is strained to that yarn's own strength, read along the yarn, not in the tip's cell.

The yarn crack (:mod:`fabric_fenicsx.fem.yarn_crack`) lets a cell crossed by a crack's line soften
as soon as its own strains damage it. At a slit's tip those strains are concentrated by the cells
themselves: the thesis's membrane passes no load between yarns (Sec. 2.1), so in its continuum an
uncut yarn at the tip carries the strain of the net section and the concentration is 1, while the
tip's cell, whose bilinear field spans several yarns and shares nodes with the opened crack, reads
1.06 to 1.32 times that, by its shape and orientation and not shrinking with its size
(docs/tear_test.md, "The slit's tip as the cells see it"). On the aligned 2 mm tear-test mesh the
concentration lies in the tip's cell alone: its neighbours along its warp yarn read 0.99 to 1.02
times the section's strain where it reads 1.23.

Here a cell crossed by a crack's line of family i joins the crack only once, in addition, its
yarn's strain away from it reaches the yarn segment's own law (the strength a root needs):

    Ebar_i(c) = median of E_i(k) over the live cells k, not cracked in family i, k != c,
                with |(x_k - x_c) . d_i| <= r_c and |(x_k - x_c) . d_i_perp| <= sqrt(A_c) / 2,

the cells on yarn i's line through c (a band one cell wide) within the neighbourhood radius r_c
the crack tracking already uses (:data:`~fabric_fenicsx.fem.yarn_crack.EXCLUSION` cell diameters),
the other family's strain the cell's own. The median, because the band also holds cells that are
not the yarn's strain: slack cells on cut yarns beside the slit and a crack's softening cells. The
surrogate decides the damage at (Ebar_i, E_j) with the segment's law; once joined, the cell softens
by its own strains with the law of equal energy, as in the yarn crack. Where the band is empty
(a panel's corner) the cell's own strain decides. ``band`` widens the band to that many cell
widths (the del zone reads three, the rows on both sides too: :mod:`fabric_fenicsx.fem.shear_lag`).
No length is added: r_c is the neighbourhood the crack tracking reads and shrinks with the
cells, while the cells' concentration, which does not shrink, stays in the tip's cell. With
``roots`` (the scenes' ``yarn_strain``) a crack's start (a root) waits for its yarn in the same
way. One rank, as the yarn crack.

Measured (docs/tear_test.md, docs/ballistic_limit.md): no tear runs from a slit before the panel
fails elsewhere, and the panel's strength agrees across the meshes within 10 %; Y90's families
part further than with the yarn crack. A candidate, not the scenes' default.
"""
from __future__ import annotations

import numpy as np

from fabric_fenicsx.fem.polygons import polygon_areas
from fabric_fenicsx.fem.yarn_crack import UNCRACKED, YarnCrack

__all__ = ["YarnTip", "grouped_median"]


def grouped_median(values: np.ndarray, group: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """(median, count) of ``values`` per group (``group``: ints in [0, n_groups)); median NaN where
    a group is empty."""
    values, group = np.asarray(values, float), np.asarray(group, np.int64)
    order = np.lexsort((values, group))
    v = values[order]
    count = np.bincount(group, minlength=n_groups)
    start = np.cumsum(count) - count
    median = np.full(n_groups, np.nan)
    has = count > 0
    lo, hi = start[has] + (count[has] - 1) // 2, start[has] + count[has] // 2
    median[has] = 0.5 * (v[lo] + v[hi])
    return median, count


class YarnTip(YarnCrack):
    """The yarn crack whose tips join only when their yarn, read along it, reaches the segment's
    law (module docstring). Arguments as :class:`~fabric_fenicsx.fem.yarn_crack.YarnCrack`."""

    def __init__(self, corners, directions, *args, roots: bool = False, band: float = 1.0, **kwargs):
        if not band > 0.0:
            raise ValueError(f"the yarn's band must be a positive number of cell widths, got {band!r}")
        super().__init__(corners, directions, *args, **kwargs)
        self.roots = bool(roots)
        """Whether a crack's start (a root) also waits for its yarn (``yarn_strain``), not only a tip."""
        self.band = float(band)
        """The width of the band a yarn is read over, in cell widths sqrt(A_c) (module docstring: 1)."""
        self.directions = np.array([np.asarray(d, float) for d in directions])
        self.width = np.sqrt(polygon_areas(np.asarray(corners, float)))
        self.tips_held = np.zeros(2, np.int64)    # cell-steps a tip waited for its yarn, per family
        self.roots_held = np.zeros(2, np.int64)   # the same for a crack's start (with ``roots``)

    def yarn_strain(self, family: int, cells: np.ndarray, E_cell: np.ndarray, live: np.ndarray,
                    skip: np.ndarray | None = None) -> np.ndarray:
        """Ebar_i of the module docstring for ``cells``, from the cells' strains ``E_cell`` of
        ``family`` (n_cells,) and the mask of live cells ``live``; a cell's own strain where its
        band holds no other cell. ``E_cell`` may be (k, n_cells): k quantities read over the same
        band, (k, len(cells)) returned. ``skip`` (2, len(cells)): per cell a span (from, to) of
        x . d_j (the other family's direction) whose cells the band leaves out (a crack's cut
        yarns; NaN: none)."""
        return self.band_median(cells, self.band_members(family, cells, live, skip), E_cell)

    def band_members(self, family: int, cells: np.ndarray, live: np.ndarray,
                     skip: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(member, owner): the cells of each of ``cells``' bands (:meth:`yarn_strain`, the same
        arguments), flat, and the position in ``cells`` whose band each belongs to. They change
        only with the cracks and the live cells: a caller that knows these unchanged may keep
        them for :meth:`band_median`."""
        other, owner = self.neighbourhoods(cells)
        d = self.centres[other] - self.centres[cells[owner]]
        t = self.directions[family]
        along, across = d @ t, d @ np.array([-t[1], t[0]])
        keep = ((other != cells[owner]) & live[other] & (self.kind[family, other] == UNCRACKED)
                & (np.abs(along) <= self.radius[cells[owner]]) & (np.abs(across) <= 0.5 * self.band * self.width[cells[owner]]))
        if skip is not None:
            at = self.at[1 - family, other]
            keep &= ~((at > skip[0, owner]) & (at < skip[1, owner]))
        return other[keep], owner[keep]

    @staticmethod
    def band_median(cells: np.ndarray, members: tuple[np.ndarray, np.ndarray], E_cell: np.ndarray) -> np.ndarray:
        """:meth:`yarn_strain` over the bands ``members`` (:meth:`band_members` of ``cells``)."""
        member, owner = members
        values = np.atleast_2d(E_cell)
        out = np.empty((values.shape[0], cells.size))
        for k, value in enumerate(values):
            median, count = grouped_median(value[member], owner, cells.size)
            out[k] = np.where(count > 0, median, value[cells])
        return out if np.ndim(E_cell) == 2 else out[0]

    def _tips_ready(self, family: int, tips, surrogate, points, E1, E2, a_old) -> np.ndarray:
        ready = self._yarn_reaches_segment(family, tips, surrogate, points, E1, E2, a_old)
        self.tips_held[family] += int(np.count_nonzero(~ready))
        return ready

    def _roots_ready(self, family: int, roots, surrogate, points, E1, E2, a_old) -> np.ndarray:
        if not self.roots:
            return np.ones(len(roots), dtype=bool)
        ready = self._yarn_reaches_segment(family, roots, surrogate, points, E1, E2, a_old)
        self.roots_held[family] += int(np.count_nonzero(~ready))
        return ready

    def _yarn_reaches_segment(self, family: int, cells, surrogate, points, E1, E2, a_old) -> np.ndarray:
        """Mask of ``cells`` (sorted) whose yarn strain Ebar_i, with the cell's own strain
        of the other family, damages family i at the segment's law."""
        if len(cells) == 0:
            return np.zeros(0, dtype=bool)
        n = self.centres.shape[0]
        cell_of = points // self.npc
        count = np.bincount(cell_of, minlength=n)
        live = count > 0
        E = (E1, E2)
        E_cell = np.bincount(cell_of, weights=E[family], minlength=n) / np.maximum(count, 1)
        far = self.yarn_strain(family, cells, E_cell, live)
        at = np.flatnonzero(self.cell_mask(cells)[cell_of])
        e = [np.array(E1[at], float), np.array(E2[at], float)]
        e[family] = far[np.searchsorted(cells, cell_of[at])]
        mu, sc = self.mu_crit[:, points[at]].copy(), self.scale[:, points[at]].copy()
        mu[family], sc[family] = self.base[0][family, points[at]], self.base[1][family, points[at]]
        _, _, c1, c2 = surrogate.update(e[0], e[1], a_old[0, at], a_old[1, at],
                                        critical_stretch=mu, softening_scale=sc)
        damaged = (c1, c2)[family] < a_old[family, at]
        return self.cell_mask(cell_of[at][damaged])[cells]

    def summary(self) -> dict:
        """:meth:`YarnCrack.summary` with, per family, ``tips_held``: the cell-steps a cell on a
        crack's line, damaged by its own strains, waited for its yarn's strain (included in
        ``held``), and ``roots_held``: the same for a crack's start (``roots``; 0 without)."""
        out = super().summary()
        for i, name in enumerate(("warp", "fill")):
            out[name]["tips_held"] = int(self.tips_held[i])
            out[name]["roots_held"] = int(self.roots_held[i])
        return out

