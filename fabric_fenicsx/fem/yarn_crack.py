"""A failure rule that follows the yarns: a broken yarn family opens a crack along the other
family, through the cells that line crosses, with the energy of one yarn segment per yarn cut.

The thesis's rule (Eq. 2-25 at every point) softens whichever cells strain most, so that a tear
runs along the rows of cells and takes the energy of one row of cells (docs/tear_test.md). In a
woven fabric a warp yarn breaks across its own axis and the break runs to the next warp yarn at
the same place: the tear of the warp runs along the fill, and the work it takes per yarn is that
of one segment h0 (the yarn spacing, on which the fibril statistics of Eq. 2-25 are defined).
This rule gives the cells both, per yarn family i (warp 0, fill 1), with direction d_i:

* **Where a yarn may soften** (crack tracking, after Cervera and Chiumenti, Comput. Methods
  Appl. Mech. Eng. 196 (2006) 304-320, with the crack's direction that of the other yarns):
  every cracked cell carries the position ``line`` = x . d_i of its crack, a line along d_j. A
  cell whose yarn i would start to damage is admitted to soften if the line of a cracked cell
  within ``exclusion`` of its own size crosses it (the crack's tip runs on along the line); it is
  held intact if cracked cells are near but none of their lines crosses it (it lies beside the
  crack, which runs along the yarns, not along the cells); with no cracked cell near it starts a
  crack of its own on the line through its centre (a root).
* **How much energy a cell takes** (:mod:`fabric_fenicsx.material.crack_energy`): a cell at a
  crack's tip breaks with the work of one segment per yarn: its law is that of equal energy over
  its extent c along d_i, ratio h0 / c. A root keeps the segment's own law (its strength: where
  no crack concentrates the strain, a cell of any size is as strong as its yarns). The slit of a
  test, or any crack a scene starts with, is given by :meth:`YarnCrack.add_crack`.

The rule sits between the surrogate's damage update and the stresses (``YarnStress.failure``):
it hands the points their laws (:meth:`YarnCrack.laws`), then accepts or takes back each new
damage (:meth:`YarnCrack.admit`). A cell found far from any crack and short of the segment's
strength is asked with the segment's law from then on, until a crack is added near it: the damage
the tip's law would give there is taken back anyway, and asking twice a step made the step's
constitutive update 1.8 to 2.4 times as long (docs/ballistic_limit.md). Removal (deletion,
erosion) is unchanged. One rank: the cracks near a cell on another rank are not exchanged; the
rule refuses a communicator of more.
"""
from __future__ import annotations

from itertools import chain

import numpy as np

from fabric_fenicsx.material.crack_energy import equal_energy_law, softening_moments

__all__ = ["YarnCrack", "EXCLUSION", "CRACK_COLUMNS", "KINDS", "BROKEN_ALPHA", "cell_extents"]

EXCLUSION = 3.0
"""Radius of a cell's neighbourhood, in units of its diameter (longest corner-to-corner
distance): the cracked cells nearer than this decide whether it may soften, and a new crack
starts only farther away. On a mesh not aligned with the yarns the strain beside a crack's tip
can exceed that on its line a few cells away: with 1.5 diameters a second crack started 2.5 mm
beside the first ahead of its tip on the 30-degree 1 mm tear-test mesh; 3 hold it on the line."""

BROKEN_ALPHA = 0.5
"""A cell's yarn family counts as broken once its alpha (the fraction of fibrils left) reaches
this: the tear test's measure of a broken cell, and when a crack cell lengthens its crack for the
shear-lag tip (:mod:`fabric_fenicsx.fem.shear_lag`)."""

UNCRACKED, ROOT, TIP, GIVEN = 0, 1, 2, 3
"""What a cell is in a family's crack: not cracked; the start of a crack (the segment's law);
on a crack's line behind its start (the law of equal energy); given (a slit)."""


KINDS = ("uncracked", "root", "tip", "given")
"""The names of the kinds above, by their code."""

CRACK_COLUMNS = ("time_s", "family", "kind", "cell", "x_m", "y_m", "line_m")
"""cracks.csv, one row per cell that joined a crack, in the order they joined (within a step: the
warp's first, then by cell number): ``time_s`` the t_n of the step whose strains cracked it
(:attr:`YarnCrack.time`); ``family`` warp or fill, the yarn that broke; ``kind`` root, tip or
given (:data:`KINDS`); ``cell`` its local number; ``x_m``, ``y_m`` its reference centre (m);
``line_m`` the position x . d_i of the crack's line it joined (m)."""


def cell_extents(corners: np.ndarray, direction) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): per cell (reference corners (n, k, 2)) the range of x . d over its corners."""
    p = np.asarray(corners, float) @ np.asarray(direction, float)
    return p.min(axis=1), p.max(axis=1)


class YarnCrack:
    """The cracks of both yarn families on one rank's cells (see the module docstring).

    corners: reference corners of the cells (n, k, 2); directions: the yarns' unit vectors
    (d1, d2); fabric: its damage law and yarn lengths; mu_crit, scale: each point's segment law
    (2, n_points), the fabric's or a strength scatter's; points_per_cell: points of a cell,
    consecutive; segment: h0 per family (m), default the unit cell's length along each yarn."""

    def __init__(self, corners, directions, fabric, mu_crit, scale, points_per_cell: int = 1,
                 segment=None, exclusion: float = EXCLUSION, comm=None):
        from scipy.spatial import cKDTree

        if comm is not None and comm.size > 1:
            raise ValueError("the yarn-crack failure rule runs on one rank only (its cracks are not "
                             "exchanged between ranks); run without mpirun")
        corners = np.asarray(corners, float)
        self.npc = int(points_per_cell)
        n_cells = corners.shape[0]
        self.law = fabric.damage
        self.base = (np.asarray(mu_crit, float).copy(), np.asarray(scale, float).copy())
        if self.base[0].shape != (2, n_cells * self.npc):
            raise ValueError(f"mu_crit must have shape (2, {n_cells * self.npc}), got {self.base[0].shape}")
        self.segment = np.array([2 * fabric.warp.w, 2 * fabric.fill.w] if segment is None else segment, float)
        self.centres = corners.mean(axis=1)
        self.diameter = np.max(np.linalg.norm(corners[:, :, None] - corners[:, None], axis=-1), axis=(1, 2))
        self.radius = exclusion * self.diameter
        self.tree = cKDTree(self.centres)
        self.lo, self.hi, self.at = np.empty((2, n_cells)), np.empty((2, n_cells)), np.empty((2, n_cells))
        for i, d in enumerate(directions):
            self.lo[i], self.hi[i] = cell_extents(corners, d)
            self.at[i] = self.centres @ np.asarray(d, float)
        self.kind = np.zeros((2, n_cells), np.int8)
        self.line = np.full((2, n_cells), np.nan)
        # each cell's last classification against a family's cracks, valid until a crack is added
        # within the largest radius of it (cracks are only ever added: see _classified)
        self._state = np.zeros((2, n_cells), np.int8)
        self._state_line = np.zeros((2, n_cells))
        self._stale = np.ones((2, n_cells), dtype=bool)
        self._reach = float(self.radius.max(initial=0.0))
        self._on_segment = np.zeros((2, n_cells), dtype=bool)   # asked with the segment's law
        # the law of equal energy at a crack's tip, per point (cells' extents repeated per point)
        self.tip = (np.empty_like(self.base[0]), np.empty_like(self.base[1]))
        for i in range(2):
            I0, I1, _ = softening_moments(fabric.damage, fabric.yarns[i].mu_crit)
            ratio = np.repeat(self.segment[i] / (self.hi[i] - self.lo[i]), self.npc)
            m, s = equal_energy_law(self.base[0][i] - 1.0, self.base[1][i], ratio, I0, I1)
            self.tip[0][i], self.tip[1][i] = 1.0 + m, s
        # the laws the points are asked with: the tip's until a cell starts a crack of its own
        self.mu_crit, self.scale = self.tip[0].copy(), self.tip[1].copy()
        self.held = np.zeros(2, np.int64)   # cell-steps whose new damage was taken back, per family
        self.time = 0.0
        """Time stamp (s) of the cracks started from now on: the run sets it before each step."""
        self._joined: list[np.ndarray] = []   # rows of CRACK_COLUMNS not yet handed out

    @classmethod
    def on_cells(cls, corners, directions, fabric, points_per_cell: int = 1, laws=None, comm=None, **options):
        """The rule over cells whose points have the segment laws ``laws`` = (mu_crit, scale), each
        (n_points, 2) (a strength scatter's field), or None (the fabric's law everywhere);
        ``options`` go to the class (a subclass's own)."""
        n = np.asarray(corners).shape[0] * int(points_per_cell)
        if laws is None:
            mu_crit = np.repeat(np.array([[fabric.warp.mu_crit], [fabric.fill.mu_crit]]), n, axis=1)
            scale = np.ones((2, n))
        else:
            mu_crit, scale = (np.asarray(x, float).T for x in laws)
        return cls(corners, directions, fabric, mu_crit, scale, points_per_cell, comm=comm, **options)

    def damage_range(self):
        """The lowest critical stretch per family the laws can take (a surrogate's table must hold
        damage from there): :class:`~fabric_fenicsx.material.scatter.DamageRange`."""
        from fabric_fenicsx.material.scatter import DamageRange, failure_stretch

        lo = np.minimum(self.tip[0].min(axis=1, initial=np.inf), self.base[0].min(axis=1, initial=np.inf))
        hi = np.array([failure_stretch(self.law, self.base[0][i], self.base[1][i]).max(initial=0.0)
                       for i in range(2)])
        return DamageRange(lo, hi)

    def add_crack(self, cells, family: int, line: float) -> None:
        """Cells cut at the start (a slit): family ``family``'s crack on the line x . d = ``line``."""
        cells = np.asarray(cells, np.int64)
        self.kind[family, cells] = GIVEN
        self.line[family, cells] = float(line)
        self._cracks_added(family, cells)

    def new_cracks(self) -> np.ndarray:
        """The cells that joined a crack since the last call: rows of :data:`CRACK_COLUMNS`
        (family and kind as their codes: 0 warp, 1 fill; :data:`KINDS`)."""
        rows = np.concatenate(self._joined) if self._joined else np.zeros((0, len(CRACK_COLUMNS)))
        self._joined = []
        return rows

    def summary(self) -> dict:
        """Per family (warp, fill): the cells that started a crack (``roots``), that cracked on a
        crack's line (``tips``), that were cut at the start (``given``), and the cell-steps whose
        new damage was taken back (``held``: beside a crack; or away from any and short of the
        segment's own strength, counted once: such a cell is then asked with the segment's law,
        under which it has no new damage to take back, until a crack is added near it)."""
        return {name: {"roots": int(np.count_nonzero(self.kind[i] == ROOT)),
                       "tips": int(np.count_nonzero(self.kind[i] == TIP)),
                       "given": int(np.count_nonzero(self.kind[i] == GIVEN)), "held": int(self.held[i])}
                for i, name in enumerate(("warp", "fill"))}

    def laws(self, points) -> dict:
        """The damage laws of ``points`` (indices or a slice) for the surrogate's update."""
        return {"critical_stretch": self.mu_crit[:, points], "softening_scale": self.scale[:, points]}

    def _cracks_added(self, family: int, cells: np.ndarray) -> np.ndarray:
        """Record the newly cracked ``cells`` of ``family`` (:meth:`new_cracks`) and mark stale the
        classification of every cell whose neighbourhood may hold one of them (all within the
        largest radius: a superset); returns those cells (with repeats)."""
        near = np.zeros(0, np.int64)
        if cells.size:
            n = cells.size
            self._joined.append(np.column_stack((np.full(n, self.time), np.full(n, family),
                                                 self.kind[family, cells], cells, self.centres[cells],
                                                 self.line[family, cells])))
            near = self.tree.query_ball_point(self.centres[cells], self._reach)
            near = np.fromiter(chain.from_iterable(near), np.int64)
            self._stale[family, near] = True
            back = near[self._on_segment[family, near] & (self.kind[family, near] == UNCRACKED)]
            self._use_law(family, np.unique(back), segment=False)
        return near

    def _use_law(self, family: int, cells: np.ndarray, segment: bool) -> None:
        """Ask the points of ``cells`` with the segment's law (``segment``) or the tip's for
        ``family`` from the next update on."""
        p = (cells[:, None] * self.npc + np.arange(self.npc)).ravel()
        law = self.base if segment else self.tip
        self.mu_crit[family, p], self.scale[family, p] = law[0][family, p], law[1][family, p]
        self._on_segment[family, cells] = segment

    def _classified(self, family: int, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_classify`, from the last classification where no crack was added near since:
        a cell's state depends only on the cracked cells within its radius, and a crack once
        added stays, so the stored state is exactly what classifying again would give."""
        stale = cells[self._stale[family, cells]]
        if stale.size:
            self._state[family, stale], self._state_line[family, stale] = self._classify(family, stale)
            self._stale[family, stale] = False
        return self._state[family, cells], self._state_line[family, cells].copy()

    def cell_mask(self, cells: np.ndarray) -> np.ndarray:
        """The cells' mask, True at ``cells``: ``cell_mask(cells)[cell_of]`` is ``np.isin(cell_of,
        cells)`` without its sort or its pass per cell."""
        mask = np.zeros(self.centres.shape[0], dtype=bool)
        mask[cells] = True
        return mask

    def neighbourhoods(self, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(other, owner): the cells within each of ``cells``' radius (itself included), flat, and
        the position in ``cells`` whose neighbourhood each belongs to."""
        near = self.tree.query_ball_point(self.centres[cells], self.radius[cells])
        sizes = np.fromiter(map(len, near), np.int64, cells.size)
        other = np.fromiter(chain.from_iterable(near), np.int64, int(sizes.sum()))
        return other, np.repeat(np.arange(cells.size), sizes)

    def _classify(self, family: int, cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(state, line) of candidate ``cells`` against the cracks of ``family`` now: TIP with the
        line that crosses it (the nearest such cell's), UNCRACKED where cracked cells are near but
        none crosses it (held), ROOT where none is near (a crack of its own if the segment's law
        damages it)."""
        other, owner = self.neighbourhoods(cells)
        cracked = self.kind[family, other] != UNCRACKED
        other, owner = other[cracked], owner[cracked]
        state = np.where(np.bincount(owner, minlength=cells.size) > 0, UNCRACKED, ROOT).astype(np.int8)
        line = self.at[family, cells].copy()
        lines = self.line[family, other]
        crossing = (lines >= self.lo[family, cells[owner]]) & (lines <= self.hi[family, cells[owner]])
        other, owner, lines = other[crossing], owner[crossing], lines[crossing]
        if owner.size:
            distance = np.linalg.norm(self.centres[other] - self.centres[cells[owner]], axis=1)
            order = np.lexsort((distance, owner))
            first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]
            state[owner[first]] = TIP
            line[owner[first]] = lines[first]
        return state, line

    def admit(self, surrogate, points, E1, E2, a_old, b_new):
        """Accept, take back or redo the new damage ``b_new`` (2, m) of the live ``points`` (global
        point indices, (m,)) from the previous ``a_old`` (2, m) at the strains (E1, E2) the
        surrogate's update saw. Returns (b, redo): the damage to keep, and the positions (into
        ``points``) whose stresses must be evaluated again at it."""
        b = b_new.copy()
        redo = []
        npc = self.npc
        for i in range(2):
            cell_of = points // npc
            new = (b_new[i] < a_old[i]) & (self.kind[i, cell_of] == UNCRACKED)
            if not new.any():
                continue
            cells = np.unique(cell_of[new])
            state, line = self._classified(i, cells)
            tip = state == TIP
            ready = self._tips_ready(i, cells[tip], surrogate, points, E1, E2, a_old)
            tips, late = cells[tip][ready], cells[tip][~ready]
            self.kind[i, tips], self.line[i, tips] = TIP, line[tip][ready]
            self._cracks_added(i, tips)
            held = np.concatenate((cells[state == UNCRACKED], late))
            roots = cells[state == ROOT]
            if roots.size:
                at = np.flatnonzero(self.cell_mask(roots)[cell_of])
                mu, sc = self.mu_crit[:, points[at]].copy(), self.scale[:, points[at]].copy()
                mu[i], sc[i] = self.base[0][i, points[at]], self.base[1][i, points[at]]
                _, _, c1, c2 = surrogate.update(E1[at], E2[at], a_old[0, at], a_old[1, at],
                                                critical_stretch=mu, softening_scale=sc)
                full = np.stack((c1, c2))
                started = np.unique(cell_of[at][full[i] < a_old[i, at]])
                started = started[self._roots_ready(i, started, surrogate, points, E1, E2, a_old)]
                started = self._one_per_neighbourhood(i, started)
                self.kind[i, started], self.line[i, started] = ROOT, self.at[i, started]
                self._cracks_added(i, started)
                go = self.cell_mask(started)[cell_of[at]]
                self._use_law(i, started, segment=True)
                b[:, at[go]] = full[:, go]
                redo.append(at[go])
                waiting = np.setdiff1d(roots, started)
                # far from any crack and short of the segment's strength: asked with the segment's
                # law until a crack is added near (the tip's law would only be taken back again)
                self._use_law(i, waiting[~self._stale[i, waiting]], segment=True)
                held = np.concatenate((held, waiting))
            self.held[i] += held.size
            back = np.flatnonzero(self.cell_mask(held)[cell_of] & new)
            b[i, back] = a_old[i, back]
            redo.append(back)
        redo = np.unique(np.concatenate(redo)) if redo else np.zeros(0, np.int64)
        return b, redo

    def _tips_ready(self, family: int, tips, surrogate, points, E1, E2, a_old) -> np.ndarray:
        """Which of the cells ``tips`` (sorted), crossed by a crack's line of ``family`` and
        damaged there by their own strains, may join the crack now (a mask): all of them here; a
        rule that reads the tip otherwise (:mod:`fabric_fenicsx.fem.yarn_tip`) holds some back."""
        return np.ones(len(tips), dtype=bool)

    def _roots_ready(self, family: int, roots, surrogate, points, E1, E2, a_old) -> np.ndarray:
        """Which of the cells ``roots`` (sorted), far from any crack of ``family`` and damaged by
        their own strains at the segment's law, may start a crack now (a mask): all of them here."""
        return np.ones(len(roots), dtype=bool)

    def _one_per_neighbourhood(self, family: int, cells: np.ndarray) -> np.ndarray:
        """Of cells starting cracks of ``family`` in the same step, those not within the
        neighbourhood of one kept before them (in index order: deterministic); the others wait,
        and the next step sees the new crack near them."""
        kept = []
        for c in cells:
            ok = True
            for k in kept:
                if np.linalg.norm(self.centres[c] - self.centres[k]) <= self.radius[c]:
                    ok = False
                    break
            if ok:
                kept.append(c)
        return np.array(kept, np.int64)
