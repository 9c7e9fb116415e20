"""The yarn crack whose tip breaks by the fabric's own concentration: the yarn beside n broken
yarns carries Hedgepeth's shear-lag factor K_n times its yarn's stretch, counted in yarn spacings.

A rule that lets a crack's tip cell decide on its own strain reads the cells' concentration, which
on this reduced element is mostly its hourglass control's coupling of neighbouring yarns (on cells
along the yarns) or nothing (on cells turned 45 degrees): a property of the mesh
(docs/tear_test.md, "What carries the load past the slit's tip"). The thesis's membrane passes no
load between yarns (Sec. 2.1); a woven fabric passes it at the crossings, and parallel yarns
loaded through a shear-lag coupling carry, in the yarn beside n broken ones, the concentration

    K_n = (4 . 6 . 8 ... (2n + 2)) / (3 . 5 . 7 ... (2n + 1))        (K_0 = 1)

(Hedgepeth, "Stress concentrations in filamentary structures", NASA TN D-882, 1961: the static
two-dimensional array), which does not depend on the coupling's stiffness: that sets only the
length over which the concentration decays along the yarn, here not resolved. This rule takes the
concentration from there and the strain from the yarn:

* **The tip** (a live cell not cracked in family i, crossed by the line of a crack of family i and
  touching that crack's broken part): it joins the crack when its yarn's stretch mu_i, at the
  strains read along the yarn away from it (both families' by :meth:`YarnTip.yarn_strain
  <fabric_fenicsx.fem.yarn_tip.YarnTip.yarn_strain>`, the median over a band one cell wide),
  raised by the load the broken yarns shed,

      mu*_i - 1 = (mu_i - 1) + (K_n - 1) c,

  damages the yarn at the segment's law (Eq. 2-25, the strength of its root), whatever its own
  strains do. n = round(a / s): a the length across the yarns of the crack's broken part that the
  tip touches, s the spacing of the yarns of family i (the other family's unit-cell length, 0.726
  mm for Zylon AS); c the mean stretch mu_i - 1 those broken yarns carried as they joined (a
  slit's yarns count as loaded like the tip's: c = mu_i - 1). Under a uniform load c = mu_i - 1
  and mu*_i - 1 = K_n (mu_i - 1), Hedgepeth's; where the broken yarns carried less (a crack run
  out of the loaded region) they shed less. A cell damaged by its own strains but not by its
  yarn's raised stretch is held (its new damage taken back).
* **The crack**: a joined cell is damaged at least as its yarn's raised stretch damages it, until
  it counts as broken (alpha_i at most 1/2, or removed), and also softens by its own strains with
  the yarn crack's law of equal energy (:mod:`fabric_fenicsx.fem.yarn_crack`). Only broken cells
  lengthen the crack for the next tip: a crack grows by one cell at a time, each after the one
  before has opened.
* **A crack's start** (a root) waits for its yarn's strain to reach the segment's law
  (``yarn_strain``): K_0 = 1.

In the membrane the cut yarns' load goes to the whole net section (every uncut yarn carries its
strain); K_n then multiplies that net-section stretch, so a finite panel's factor W / (W - a) is
counted on top of Hedgepeth's, whose far field is an infinite sheet's. The concentration is the
static one (the dynamic overshoot after a sudden break, which Hedgepeth's paper also treats, is
left out), and it assumes the crossings pass load as a shear lag, without slip: K_n grows as
sqrt(pi n / 4) without bound, so a long crack breaks yarns that carry a small part of their
strength (docs/ballistic_limit.md).

**The del zone** (``material.failure = "del_zone"``: the factor at most
:data:`SLIP_CONCENTRATION` = 2). A dry fabric's crossings pass load by friction, at most mu V
at a crossing (V the unit cell's contact force; mu 0.27 between Kevlar fibres, Sec. 4.1 after
Rebouillat). Where they slip, a broken yarn takes its load T back along its length at that
rate, over T / (mu V) crossings, and the intact yarns beside it take the load up, and give up
any excess again, at the same rate (the crossing yarn presses on the broken and the intact yarn
alike). On every line across the yarns the intact yarns' excess equals the broken yarns'
deficit; with excesses that fall monotonically away from the crack, none can exceed what the
broken yarns' recovery length lets it gather, T: the yarn beside the crack carries at most twice the load a broken yarn carried, and the
load of n broken yarns spreads over at least n intact ones (the del zone of a fabric's tear).
Neither mu nor V is left in the bound. The factor is Hedgepeth's while the crossings hold (K_n
< 2 for n <= 3) and 2 from n = 4 broken yarns on. A bound, not the slip zone solved (that
needs the crossings' shear stiffness, not in the stored sources).

The del zone's crack cells also **snap** (``snap``): a cell that joins a crack (a start, or a
tip) breaks, alpha_i at most 1/2, in the step it joins. Its yarn has reached the segment's law,
the peak of the segment's force (Eq. 2-25); a segment of a yarn many segments long cannot soften
stably past that peak, since the rest of the yarn, unloading, gives up more energy than the
segment's softening takes (a fibril bundle of Sec. 2.3 in series with the rest of its yarn).
Without it a joined cell softens only as its yarn's raised stretch, or its own strains, go on rising,
and how fast the latter rise is the cell's own concentration, a property of the mesh (on the
tear test a joined tip broke within a step on the aligned grid and after 700 N more on the
graded mesh, docs/tear_test.md). The rest of its opening follows its own strains with the yarn
crack's law of equal energy. The del zone reads its yarn over a band three cells wide
(``band = 3``, :class:`~fabric_fenicsx.fem.yarn_tip.YarnTip`): a cell spans more than a yarn, and
the first row beyond a crack spans its last slack yarn and the first loaded one; and over the
**uncut yarns** of that band only (``read_uncut``): the band's cells within the span across of
the cut yarns beside the tip are left out, since the tip's yarn is the first uncut one and what
its neighbours on the crack's side carry (slack, or loaded back by the cells' coupling, a
property of the mesh) is not its strain. It **cuts its cracks' bridges** (``close_bridges``,
:mod:`~fabric_fenicsx.fem.crack_bridges`): where two of a crack's broken cells meet at a corner
only, the yarn through that node is not cut, and the intact cell at that corner that the yarn
enters most directly joins the crack. Both rules are candidates, not the scenes' default. One
rank, as the yarn crack.
"""
from __future__ import annotations

import numpy as np

from fabric_fenicsx.fem.crack_bridges import bridge_cells, corner_nodes
from fabric_fenicsx.fem.crack_budget import unit_cell_breaking_work
from fabric_fenicsx.fem.yarn_crack import BROKEN_ALPHA, GIVEN, ROOT, TIP, UNCRACKED
from fabric_fenicsx.fem.yarn_tip import YarnTip
from fabric_fenicsx.material.crack_energy import breaking_work, softening_moments

__all__ = ["hedgepeth_concentration", "SLIP_CONCENTRATION", "ShearLag"]

_NO_POINTS = np.zeros(0, np.int64)

SLIP_CONCENTRATION = 2.0
"""The largest factor on a yarn beside broken ones where the crossings slip (module docstring,
"The del zone")."""


def hedgepeth_concentration(n) -> np.ndarray:
    """K_n of the module docstring for integer counts ``n`` >= 0 of broken yarns (array-like)."""
    n = np.asarray(n)
    if n.size and (n.min() < 0 or not np.issubdtype(n.dtype, np.integer)):
        raise ValueError(f"the broken yarns' count must be an integer >= 0, got {n.ravel()[0]!r}")
    k = np.arange(1, int(n.max(initial=0)) + 1)
    table = np.concatenate(([1.0], np.cumprod((2.0 * k + 2.0) / (2.0 * k + 1.0))))
    return table[n]


def touching_pieces(lo, hi, length_lo, length_hi, weights, at_lo, at_hi, gap):
    """The broken cells of one crack, each spanning [lo, hi] across the yarns (its corners'
    extent), joined into pieces where these overlap or lie within ``gap`` of each other; a piece's
    length is max(length_hi) - min(length_lo) over its cells (each cell counted by its width
    sqrt(area) about its centre, so that the cells turned to the yarns, whose corners reach past
    their neighbours', do not lengthen it). Per candidate spanning [at_lo, at_hi] (arrays), over
    the pieces it touches within ``gap`` (the piece it ends, or the two it would bridge): (span,
    sums, reach), their summed length, the sums of the cells' ``weights`` (m, k) columns (0 for
    none) and the extent across they span (their length's ends), (2, candidates) (NaN for none).
    Vectorised."""
    order = np.argsort(lo)
    lo, hi, length_lo, length_hi, weights = lo[order], hi[order], length_lo[order], length_hi[order], weights[order]
    start = np.flatnonzero(np.r_[True, lo[1:] > np.maximum.accumulate(hi)[:-1] + gap])
    p_lo, p_hi = lo[start], np.maximum.reduceat(hi, start)
    p_from, p_to = np.minimum.reduceat(length_lo, start), np.maximum.reduceat(length_hi, start)
    p_len = p_to - p_from
    p_sum = np.add.reduceat(weights, start, axis=0)
    span, sums = np.zeros(np.size(at_lo)), np.zeros((np.size(at_lo), weights.shape[1]))
    reach = np.full((2, np.size(at_lo)), np.nan)   # the touched pieces' extent across (from, to)
    last = np.searchsorted(p_lo, at_hi + gap, side="right") - 1   # the last piece starting before
    for k in (last, last - 1):
        kk = np.clip(k, 0, p_lo.size - 1)
        touches = (k >= 0) & (p_hi[kk] >= at_lo - gap) & (p_lo[kk] <= at_hi + gap)
        span += np.where(touches, p_len[kk], 0.0)
        sums += np.where(touches[:, None], p_sum[kk], 0.0)
        reach[0] = np.where(touches, np.fmin(reach[0], p_from[kk]), reach[0])
        reach[1] = np.where(touches, np.fmax(reach[1], p_to[kk]), reach[1])
    return span, sums, reach


class ShearLag(YarnTip):
    """The yarn crack whose tips break by their yarn's stretch raised by Hedgepeth's concentration
    (module docstring). Arguments as :class:`~fabric_fenicsx.fem.yarn_crack.YarnCrack`."""

    def __init__(self, corners, directions, *args, concentration_cap: float = np.inf, snap: bool = False,
                 close_bridges: bool = False, read_uncut: bool = False, budget: bool = False, **kwargs):
        if not concentration_cap >= 1.0:
            raise ValueError(f"the concentration's cap must be at least 1, got {concentration_cap!r}")
        kwargs.setdefault("roots", True)
        super().__init__(corners, directions, *args, **kwargs)
        self.cap = float(concentration_cap)
        self.snap = bool(snap)
        """Whether a crack cell breaks (alpha at most 1/2) in the step it joins (module docstring)."""
        self.corners = np.asarray(corners, float)
        self.nodes = corner_nodes(self.corners) if close_bridges else None
        """The cells' corner nodes where the rule cuts its cracks' bridges (module docstring), else None."""
        self.bridges_cut = np.zeros(2, np.int64)   # cells that joined a crack to cut a bridge, per family
        self._bridged_at = [None, None]            # the broken cells whose bridges were last cut
        self.read_uncut = bool(read_uncut)
        """Whether a tip's yarn is read over the uncut yarns of its band only (module docstring)."""
        if budget and not self.snap:
            raise ValueError("the budget breaks snapped crack cells: it needs snap=True")
        self.budget = bool(budget)
        """Whether a snapped crack cell holds alpha 1/2 and breaks through at one segment's work per
        yarn (:mod:`~fabric_fenicsx.fem.crack_budget`; the material asks :meth:`budgets`)."""
        self._work = None   # W_i per point (2, n_points), J/m^2: at the first ask (needs the surrogate)
        n = self.centres.shape[0]
        self.broken = np.zeros((2, n), dtype=bool)
        self.near = np.zeros((2, n), dtype=bool)   # within the largest radius of a crack of the family
        self.joined = np.zeros(2, np.int64)        # cells that joined by the concentration, per family
        self.largest = np.zeros(2, np.int64)       # the largest n a joining tip saw, per family
        self.carried = np.full((2, n), np.nan)     # mu_i - 1 a crack cell's yarn carried as it joined
        self._raised_key, self._raised_kept = [None, None], [None, None]   # see _raised_laws
        self.spacing = self.segment[::-1]          # family i's yarns lie the other family's segment apart
        extent = np.array([np.ptp(self.at[1 - i]) + self.width.max(initial=0.0) for i in range(2)])
        self.k_max = self.concentration(np.ceil(extent / self.spacing).astype(np.int64))
        # the lowest critical stretch a raised law takes: the weakest segment's under the largest K
        self.mu_floor = 1.0 + (self.base[0].min(axis=1, initial=np.inf) - 1.0) / self.k_max

    def concentration(self, n) -> np.ndarray:
        """The factor on the tip's yarn beside ``n`` broken yarns: K_n, at most the cap."""
        return np.minimum(hedgepeth_concentration(n), self.cap)

    def damage_range(self):
        """:meth:`YarnCrack.damage_range`, down to the segment laws under the largest K_n the
        panel's extent allows."""
        out = super().damage_range()
        out.mu_crit_min[:] = np.minimum(out.mu_crit_min, self.mu_floor)
        return out

    def _cracks_added(self, family: int, cells: np.ndarray) -> np.ndarray:
        near = super()._cracks_added(family, cells)
        self.near[family, near] = True
        self.broken[family, cells[self.kind[family, cells] == GIVEN]] = True   # a slit
        return near

    def _tips_ready(self, family: int, tips, surrogate, points, E1, E2, a_old) -> np.ndarray:
        # the tips whose yarn's raised stretch breaks them joined in admit before the base class
        # asks; these are damaged by their own strains only, and wait
        self.tips_held[family] += len(tips)
        return np.zeros(len(tips), dtype=bool)

    def admit(self, surrogate, points, E1, E2, a_old, b_new):
        """:meth:`YarnCrack.admit`, with the tips that their yarn's raised stretch damages joined
        first, and every crack cell not yet broken damaged at least as that stretch damages it
        (module docstring)."""
        cell_of = points // self.npc
        count = np.bincount(cell_of, minlength=self.centres.shape[0])
        live = count > 0
        # both strains of the cells: a yarn's band reads the fill's too, which sets the warp's
        # crimp (Eq. 2-17 ff.); none to read before a crack is near
        E_cell = (np.stack([np.bincount(cell_of, weights=E, minlength=count.size) for E in (E1, E2)])
                  / np.maximum(count, 1) if self.near.any() else None)
        driven = []
        for i in range(2):
            opened = (self.kind[i] != UNCRACKED) & ~self.broken[i]
            self.broken[i] |= opened & ~live
            self.broken[i, cell_of[opened[cell_of] & (a_old[i] <= BROKEN_ALPHA)]] = True
            driven.append(self._raised(i, surrogate, points, cell_of, live, E_cell, a_old))
        before = self.kind == ROOT
        b, redo = super().admit(surrogate, points, E1, E2, a_old, b_new)
        self._record_roots(np.argwhere((self.kind == ROOT) & ~before), surrogate, cell_of, E1, E2)
        more = [redo]
        for i, (at, damage) in enumerate(driven):
            lower = damage < b[i, at]
            b[i, at[lower]] = damage[lower]
            more.append(at[lower])
        if self.nodes is not None:
            for i in range(2):
                self._cut_bridges(i, live)
        if self.snap:
            for i in range(2):
                joined = ((self.kind[i] == ROOT) | (self.kind[i] == TIP)) & ~self.broken[i]
                at = np.flatnonzero(joined[cell_of] & (b[i] > BROKEN_ALPHA))
                b[i, at] = BROKEN_ALPHA
                more.append(at)
        return b, np.unique(np.concatenate(more))

    def budgets(self, surrogate, family: int, points, a_old, b) -> tuple[np.ndarray, np.ndarray]:
        """(at, budget): the positions in ``points`` of family ``family``'s snapped crack cells'
        points not yet broken through (a root's or a tip's, alpha at most 1/2 after this step's
        admit, ``b``, and above 0 before it, ``a_old``; each indexed by family, (2, m) or a pair),
        and their budgets per unit reference area (J/m^2, :mod:`~fabric_fenicsx.fem.crack_budget`).
        None of them unless ``budget``."""
        if not self.budget:
            return _NO_POINTS, np.zeros(0)
        cell_of = points // self.npc
        joined = (self.kind[family] == ROOT) | (self.kind[family] == TIP)
        at = np.flatnonzero(joined[cell_of] & (b[family] <= BROKEN_ALPHA) & (a_old[family] > 0.0))
        if self._work is None:
            self._work = self._breaking_works(surrogate)
        cells = cell_of[at]
        ratio = np.minimum(self.segment[family] / (self.hi[family, cells] - self.lo[family, cells]), 1.0)
        return at, ratio * self._work[family, points[at]]

    def _breaking_works(self, surrogate) -> np.ndarray:
        """W_i per point and family (J/m^2): the unit cell's, scaled by the point's law's
        straight-yarn work over the fabric's (:mod:`~fabric_fenicsx.fem.crack_budget`)."""
        out = np.empty_like(self.base[0])
        for i in range(2):
            W = unit_cell_breaking_work(surrogate, i)
            I0, I1, _ = softening_moments(self.law, surrogate.fabric.yarns[i].mu_crit)
            own = breaking_work(self.base[0][i] - 1.0, self.base[1][i], I0, I1)
            fabric = breaking_work(surrogate.fabric.yarns[i].mu_crit - 1.0, 1.0, I0, I1)
            out[i] = W * own / fabric
        return out

    def _cut_bridges(self, family: int, live: np.ndarray) -> None:
        """Join to family ``family``'s crack the cells that cut its bridges
        (:func:`~fabric_fenicsx.fem.crack_bridges.bridge_cells`; removed cells count as broken),
        each on the line of a crack cell at its bridge and as loaded as that cell's yarn was."""
        cut = self.broken[family] | ~live
        if self._bridged_at[family] is not None and np.array_equal(cut, self._bridged_at[family]):
            return                                   # the same crack: no new bridge
        self._bridged_at[family] = cut
        cells, via = bridge_cells(self.corners, self.nodes, cut, self.directions[family])
        new = self.kind[family, cells] == UNCRACKED
        cells, via = cells[new], via[new]
        if cells.size == 0:
            return
        self.kind[family, cells], self.line[family, cells] = TIP, self.line[family, via]
        self.carried[family, cells] = self.carried[family, via]
        self.bridges_cut[family] += cells.size
        self._cracks_added(family, cells)

    def _record_roots(self, started, surrogate, cell_of, E1, E2) -> None:
        """The stretch mu_i - 1 that each new root's yarn carried as it started (its own strains,
        the yarns intact; the mean over its points): ``started`` rows (family, cell)."""
        for family in range(2):
            cells = started[started[:, 0] == family, 1]
            if cells.size == 0:
                continue
            at = np.flatnonzero(self.cell_mask(cells)[cell_of])
            ones = np.ones(at.size)
            mu = surrogate.evaluate(E1[at], E2[at], ones, ones)[2 + family]
            where = np.searchsorted(cells, cell_of[at])
            self.carried[family, cells] = np.bincount(where, weights=mu, minlength=cells.size) / \
                np.bincount(where, minlength=cells.size) - 1.0

    def _raised(self, family, surrogate, points, cell_of, live, E_cell, a_old):
        """(at, damage): the positions (into ``points``) of the tips of ``family``'s cracks and of
        its crack cells not yet broken, and the damage of family ``family`` there at their yarn's
        raised stretch mu* (module docstring, the segment's law), from the cells' mean strains
        ``E_cell`` (2, n_cells); the tips it damages join."""
        crack = self._raised_laws(family, points, cell_of, live)
        if crack is None:
            return np.zeros(0, np.int64), np.zeros(0)
        cells, line, n_broken, members, at, where, mu_raised, scale_raised = crack
        far = self.band_median(cells, members, E_cell)
        e = [far[0][where], far[1][where]]
        mu, sc = self.mu_crit[:, points[at]].copy(), self.scale[:, points[at]].copy()
        mu[family], sc[family] = mu_raised, scale_raised
        damage = surrogate.update(e[0], e[1], a_old[0, at], a_old[1, at], critical_stretch=mu,
                                  softening_scale=sc)[2 + family]
        hit = damage < a_old[family, at]
        go = np.unique(cell_of[at][hit & (self.kind[family, cell_of[at]] == UNCRACKED)])
        if go.size:
            pick = np.searchsorted(cells, go)
            ones = np.ones(go.size)
            carried = surrogate.evaluate(far[0][pick], far[1][pick], ones, ones)[2 + family] - 1.0
            self.carried[family, go] = carried
            self.kind[family, go], self.line[family, go] = TIP, line[pick]
            self.joined[family] += go.size
            self.largest[family] = max(int(self.largest[family]), int(n_broken[pick].max()))
            self._cracks_added(family, go)
        return at[hit], damage[hit]

    def _raised_laws(self, family, points, cell_of, live):
        """What :meth:`_raised` reads of the cracks: its cells (tips and crack cells not broken,
        touching a broken part, sorted), their lines and broken yarns' counts, the cells' bands
        (:meth:`~fabric_fenicsx.fem.yarn_tip.YarnTip.band_members`), the positions in ``points``
        of their points and which cell each is, and family ``family``'s raised law there (mu*_i
        as the segment's law of mu_i: critical stretch and scale); None where no cell touches a
        broken part. It depends on the cracks (their cells, lines, broken cells and what their
        yarns carried) and the live points only, which change in a few steps of a run, and is
        kept until one of them does (the state compared whole: 10 us a call on 2433 cells)."""
        key = tuple(x.tobytes() for x in (self.kind[family], self.line[family], self.broken[family],
                                          self.near[family], self.carried[family], points))
        if self._raised_key[family] == key:
            return self._raised_kept[family]
        self._raised_key[family], self._raised_kept[family] = key, None
        near = self.near[family] & live & ~self.broken[family]
        candidates = np.flatnonzero(near & (self.kind[family] == UNCRACKED))
        state, line = self._classified(family, candidates)
        tips = candidates[state == TIP]
        opened = np.flatnonzero(near & (self.kind[family] != UNCRACKED))
        cells = np.concatenate((tips, opened))
        line = np.concatenate((line[state == TIP], self.line[family, opened]))
        n_broken, given, shed, cut = self._broken_yarns(family, cells, line)
        keep = n_broken > 0
        if not keep.any():
            return None
        order = np.argsort(cells[keep])
        cells, line, n_broken, given, shed = (x[keep][order] for x in (cells, line, n_broken, given, shed))
        cut = cut[:, keep][:, order]
        members = self.band_members(family, cells, live, skip=cut if self.read_uncut else None)
        at = np.flatnonzero(self.cell_mask(cells)[cell_of])
        where = np.searchsorted(cells, cell_of[at])
        # mu* - 1 = a (mu - 1) + b as the segment's law of mu: critical 1 + (m - b) / a, scale s / a;
        # where the shed load b alone passes the strength m the law starts at the table's floor
        K = self.concentration(n_broken)[where]
        a = 1.0 + (K - 1.0) * given[where]
        b = (K - 1.0) * (1.0 - given[where]) * shed[where]
        mu = np.maximum(1.0 + (self.base[0][family, points[at]] - 1.0 - b) / a, self.mu_floor[family])
        self._raised_kept[family] = (cells, line, n_broken, members, at, where, mu,
                                     self.base[1][family, points[at]] / a)
        return self._raised_kept[family]

    def _broken_yarns(self, family: int, tips: np.ndarray, line: np.ndarray):
        """Per tip, of the broken part of the crack on its ``line`` that it touches: (n, given,
        shed, cut): n = round(a / s) its yarns (a its length across family ``family``'s yarns; 0:
        it touches none), the fraction of its width given (a slit: its yarns count as loaded like
        the tip's), the mean stretch mu - 1 its other yarns carried as they joined, and the span
        (from, to) of its cut yarns across, x . d_j (2, tips; NaN where it touches none)."""
        j = 1 - family
        half = 0.5 * self.width
        gap = 0.05 * float(np.median(self.width))   # neighbours' corners meet up to round-off
        n_broken, given, shed = np.zeros(tips.size, np.int64), np.zeros(tips.size), np.zeros(tips.size)
        cut = np.full((2, tips.size), np.nan)
        broken = np.flatnonzero(self.broken[family])
        for value in np.unique(line):
            on = broken[self.line[family, broken] == value]
            mine = np.flatnonzero(line == value)
            if on.size == 0:
                continue
            c = tips[mine]
            is_given = self.kind[family, on] == GIVEN
            carried = np.where(is_given, 0.0, np.nan_to_num(self.carried[family, on]))
            weights = np.column_stack((self.width[on], self.width[on] * is_given, self.width[on] * carried))
            span, sums, reach = touching_pieces(self.lo[j, on], self.hi[j, on], self.at[j, on] - half[on],
                                         self.at[j, on] + half[on], weights, self.lo[j, c], self.hi[j, c], gap)
            n_broken[mine] = np.rint(span / self.spacing[family]).astype(np.int64)
            total = np.maximum(sums[:, 0], np.finfo(float).tiny)
            given[mine] = sums[:, 1] / total
            shed[mine] = sums[:, 2] / np.maximum(sums[:, 0] - sums[:, 1], np.finfo(float).tiny)
            cut[:, mine] = reach
        return n_broken, given, shed, cut

    def summary(self) -> dict:
        """:meth:`YarnTip.summary` with, per family, ``concentration_joined``: the cells that joined
        a crack by their yarn's raised stretch, and ``largest_broken_yarns``: the largest n
        a joining tip saw, and ``bridges_cut``: the cells that joined a crack to cut its bridges
        (0 unless the rule cuts them)."""
        out = super().summary()
        for i, name in enumerate(("warp", "fill")):
            out[name]["concentration_joined"] = int(self.joined[i])
            out[name]["largest_broken_yarns"] = int(self.largest[i])
            out[name]["bridges_cut"] = int(self.bridges_cut[i])
        return out
