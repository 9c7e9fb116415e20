"""The unit cell memoised as an interpolant over the membrane strains, and the vectorised
constitutive update the membrane calls at its quadrature points.

Damage scales out of the unit cell (Eq. 2-26/2-28 with both yarns' A and B scaled alike):
    response(E1, E2, alpha1, alpha2) = alpha_max * response(E1, E2, r, weaker yarn),
    r = alpha_min / alpha_max,
for the forces (P1, P2, V, Psi), while the stretches mu_i do not change. So the table is
three-dimensional: (E1, E2) on a uniform grid, and r in [0, 1] for the two cases "warp
weaker" and "fill weaker"; r = 1 (both yarns equally intact, the common case) is a 2D
layer of its own. r = 0 is a broken yarn that has left the cell.

Strains beyond the table:
  * E_i above E_i^fail = ((mu_i^complete L_i / w_i)^2 - 1) / 2: the yarn is certainly broken,
    because mu_i^max >= lambda_i w_i / L_i (its projected length cannot exceed its stretched
    length), so alpha_i = 0 exactly; this is not an extrapolation.
  * E_i below the table's lower end (compression beyond -0.06 by default, which scenario 4's free fill reaches): the lookup uses
    the lower end; such points are counted and reported.
Stresses returned by ``evaluate`` and ``update`` are tension-only (P_i >= 0): a fabric
wrinkles instead of carrying compression.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from fabric_fenicsx.surrogate import interp
from fabric_fenicsx.surrogate.kernels import damage as damage_kernel
from fabric_fenicsx.surrogate.kernels import interp as interp_kernel
from fabric_fenicsx.material.contract import DamageState
from fabric_fenicsx.material.fabric import Fabric
from fabric_fenicsx.material.scatter import point_laws
from fabric_fenicsx.surrogate.ship import ShippedTiles
from fabric_fenicsx.surrogate.tiles import (QUANTITIES, Progress, cache_key, cache_problem, default_cache_dir,
                                  load_tile, save_tile, solve_blocks, warn_unwritable)
from fabric_fenicsx.material.damage_solver import BRACKETED, UNCONVERGED, FallbackLog
from fabric_fenicsx.material.unitcell import ALPHA_BROKEN, UnitCell

_Q = {name: k for k, name in enumerate(QUANTITIES)}
WARP_WEAKER, FILL_WEAKER = 0, 1
MU_MARGIN = 2e-3
"""Stretch margin below mu_crit under which a table cell cannot start damage: the cubic
interpolant overshoots its nodes by far less (neighbouring nodes differ by ~1e-4 in mu)."""
R_LIMIT = 1e-4


class Cells(NamedTuple):
    """Interpolation cells of a batch of points: grid indices i (E1), j (E2) of each point's
    cell and its local coordinates t1, t2 in [0, 1)."""

    i: np.ndarray
    j: np.ndarray
    t1: np.ndarray
    t2: np.ndarray


class SurrogateError(RuntimeError):
    """The surrogate's damage iteration failed."""


@dataclass
class RangeStats:
    """Points that fell outside the table, accumulated over calls (see ``report``)."""

    points: int = 0
    beyond_failure: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    compression: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    E_min: np.ndarray = field(default_factory=lambda: np.full(2, np.inf))
    E_max: np.ndarray = field(default_factory=lambda: np.full(2, -np.inf))

    def record(self, E1: np.ndarray, E2: np.ndarray) -> None:
        """Count the points and widen the strain range seen (no out-of-table counts)."""
        self.points += E1.size
        for i, E in enumerate((E1, E2)):
            if E.size:
                self.E_min[i] = min(self.E_min[i], float(E.min()))
                self.E_max[i] = max(self.E_max[i], float(E.max()))

    def report(self, E_table_min: float) -> str:
        lines = [f"surrogate range: {self.points} point evaluations, strains seen "
                 f"E1 in [{self.E_min[0]:.4g}, {self.E_max[0]:.4g}], "
                 f"E2 in [{self.E_min[1]:.4g}, {self.E_max[1]:.4g}]"]
        for i, yarn in enumerate(("warp", "fill")):
            if self.beyond_failure[i]:
                lines.append(f"  {self.beyond_failure[i]} points beyond complete failure of a "
                             f"straight {yarn} yarn (alpha = 0, no force)")
            if self.compression[i]:
                lines.append(f"  {self.compression[i]} points with {yarn} compressed below the table "
                             f"(E < {E_table_min:g}; looked up at its end, tension-only)")
        return "\n".join(lines)


class Surrogate:
    """The unit cell of ``fabric`` tabulated over (E1, E2, r) and interpolated.

    Parameters
    ----------
    fabric : the fabric.
    resolution : grid spacing h of E1 and E2 (default 0.002: the cheapest table of the
        surrogate report within the 0.5 % stress tolerance; see docs/surrogate.md).
    r_nodes : nodes of the relative integrity r = alpha_min / alpha_max in [0, 1], uniform
        in sqrt(r).
    order : interpolation order in (E1, E2): 3 (Catmull-Rom cubic, C1) or 1 (linear);
        sqrt(r) is interpolated linearly.
    E_min : lower end of the table (compression); the upper end follows from the fabric
        (beyond complete failure of both straight yarns).
    n_elements : unit-cell elements per half-yarn (default of :class:`UnitCell`).
    tile : grid nodes per tile side; tiles are solved only when a lookup needs them.
    cache_dir : where solved tiles are kept (default :func:`tiles.default_cache_dir`);
        ``False`` disables the disk cache. A cache that cannot be written (read-only, a file,
        a full disk) is still read; new tiles then stay in memory, said once by a
        :class:`~fabric_fenicsx.surrogate.tiles.CacheWarning`.
    shipped : where tiles missing from the cache are read (and copied into the cache) before
        they are solved: True (the tiles shipped with the package,
        :mod:`~fabric_fenicsx.surrogate.ship`), a folder of the same layout, or False; not read
        when ``cache_dir`` is False.
    damage_range : None or a strength scatter's bounds per yarn (:class:`~fabric_fenicsx.
        material.scatter.DamageRange`): the table grows by whole tiles to the highest failure
        strain (every tile as without it); each point checks damage from its own mu_crit.
    workers : processes for solving tiles (default: all cores).
    progress : show a progress bar while solving tiles.
    """

    def __init__(self, fabric: Fabric, resolution: float = 0.002, r_nodes: int = 11, order: int = 3,
                 E_min: float = -0.06, n_elements: int | None = None, tile: int = 16,
                 cache_dir: str | Path | None | bool = None, workers: int | None = None,
                 progress: bool = True, shipped: bool | str | Path = True, damage_range=None):
        if not isinstance(fabric, Fabric):
            raise ValueError(f"fabric must be a Fabric, got {fabric!r}")
        if not (isinstance(resolution, (int, float)) and 0 < resolution <= 0.01):
            raise ValueError(f"resolution must be a strain step in (0, 0.01], got {resolution!r}")
        if not (isinstance(r_nodes, int) and r_nodes >= 2):
            raise ValueError(f"r_nodes must be an integer >= 2, got {r_nodes!r}")
        if order not in interp.ORDERS:
            raise ValueError(f"order must be one of {sorted(interp.ORDERS)}, got {order!r}")
        if not (isinstance(E_min, (int, float)) and -0.4 < E_min < 0):
            raise ValueError(f"E_min must be a compressive strain in (-0.4, 0), got {E_min!r}")
        if not (isinstance(tile, int) and tile >= 4):
            raise ValueError(f"tile must be an integer >= 4, got {tile!r}")
        self.fabric = fabric
        self.order = order
        self.h = float(resolution)
        self.r_nodes = int(r_nodes)
        self.tile = int(tile)
        self.progress = progress
        self.workers = workers or (len(__import__("os").sched_getaffinity(0)) or 1)
        cell = UnitCell(fabric, n_elements=n_elements)
        self.n_elements = cell.n_elements
        self.mu_crit = cell.mu_crit.copy()
        mu_complete = np.array([fabric.damage.mu_complete(m) for m in self.mu_crit])
        self.mu_safe = self.mu_crit.copy()   # below it (less MU_MARGIN) no point starts damage
        if damage_range is not None:
            self.mu_safe = np.minimum(self.mu_safe, damage_range.mu_crit_min)
            mu_complete = np.maximum(mu_complete, damage_range.mu_complete_max)
        self.mu_complete = mu_complete
        L = np.array([fabric.warp.L, fabric.fill.L])
        self.E_fail = 0.5 * ((mu_complete * L / cell.w) ** 2 - 1.0)
        # One ghost node below E_min and above the top for the cubic kernel's taps; the node
        # count is padded to whole tiles, so that a longer table (a scatter's damage_range) only
        # adds tiles and every tile is the same, whatever the table's length.
        k_lo = math.floor(E_min / self.h + 1e-9)
        k_hi = math.ceil(self.E_fail.max() / self.h - 1e-9) + 1
        self.E_table = (k_lo * self.h, k_hi * self.h)
        self.E_lo = (k_lo - 1) * self.h
        self.n_tiles = -(-(k_hi - k_lo + 3) // self.tile)
        self.nE = self.n_tiles * self.tile
        # Uniform in sqrt(r): the weak yarn's stretch changes fastest as r -> 0, where the
        # damage law is most sensitive to it (measured: see the surrogate report).
        self.r_grid = np.linspace(0.0, 1.0, self.r_nodes) ** 2
        nq = len(QUANTITIES)
        self.intact = np.full((self.nE, self.nE, nq), np.nan)
        self.damaged = np.full((2, self.nE, self.nE, self.r_nodes, nq), np.nan)
        P = self.order + 1
        self._safe = {"intact": np.zeros((self.nE, self.nE), bool),
                      "damaged": np.zeros((self.nE, self.nE), bool)}
        self._mu_top = {layer: np.full((self.nE, self.nE, 2), np.nan) for layer in self._safe}
        # Cell-major, quantities last but the polynomial: one gather fetches a point's quantities.
        self._coef = {"intact": np.full((self.nE, self.nE, nq, P, P), np.nan),
                      "damaged": np.full((2, self.nE, self.nE, self.r_nodes, nq, P, P), np.nan)}
        self.built = {"intact": np.zeros((self.n_tiles,) * 2, bool),
                      "damaged": np.zeros((self.n_tiles,) * 2, bool)}
        taps = interp.TAPS[self.order]
        self._taps = (-taps[0], taps[-1] - taps[0])  # cell i reads nodes i - lo .. i - lo + span
        self._ready = {layer: np.zeros((self.nE, self.nE), bool) for layer in self.built}
        self._kernel_quantities = {}  # quantities -> interp_kernel.lookup's spec of them
        self._law = damage_kernel.law_arguments(fabric.damage)
        settings = {"resolution": self.h, "r_nodes": self.r_nodes, "E_lo": self.E_lo,
                    "tile": self.tile, "padded": "whole tiles", "n_elements": self.n_elements, "tol": cell.tol,
                    "alpha_broken": ALPHA_BROKEN, "r_limit": R_LIMIT, "r_spacing": "sqrt"}
        self.key = cache_key(fabric.to_dict(), settings)
        self.cache_dir, self.cache_writable = None, False
        if cache_dir is not False:
            root = Path(cache_dir) if cache_dir else default_cache_dir()
            self.cache_dir = root / f"surrogate-{self.key}"
            # the root first: its reason is the one the command line's pre-flight check gives
            problem = cache_problem(root) or cache_problem(self.cache_dir)
            self.cache_writable = problem is None
            if problem:
                warn_unwritable(problem)
        self.shipped = (None if cache_dir is False or shipped is False
                        else ShippedTiles(self.key, None if shipped is True else shipped))
        self.stats = RangeStats()
        self.solves = 0
        self.build_seconds = 0.0

    # ------------------------------------------------------------------ tiles
    def _tile_nodes(self, a: int) -> np.ndarray:
        return np.arange(a * self.tile, min((a + 1) * self.tile, self.nE))

    @staticmethod
    def _tile_name(layer: str, a: int, b: int) -> str:
        """A tile's name: its layer and place in the table (its file's stem, in its checksum)."""
        return f"{layer}_{a}_{b}"

    def _tile_path(self, layer: str, a: int, b: int) -> Path | None:
        return None if self.cache_dir is None else self.cache_dir / f"{self._tile_name(layer, a, b)}.npz"

    def ensure_tiles(self, layer: str, tiles) -> None:
        """Solve (or load from the cache) the given tiles [(a, b), ...] of ``layer``."""
        import time
        tiles = [(int(a), int(b)) for a, b in tiles if not self.built[layer][a, b]]
        if not tiles:
            return
        if layer == "damaged":
            self.ensure_tiles("intact", tiles)
        t0 = time.perf_counter()
        nr = self.r_nodes
        todo = []
        for a, b in tiles:
            ia, jb = self._tile_nodes(a), self._tile_nodes(b)
            shape = ((len(ia), len(jb), len(QUANTITIES)) if layer == "intact"
                     else (2, len(ia), len(jb), nr - 1, len(QUANTITIES)))
            path = self._tile_path(layer, a, b)
            values = load_tile(path, self.key, shape, self._tile_name(layer, a, b)) if path else None
            if values is None and self.shipped is not None:
                values = self.shipped.load(self._tile_name(layer, a, b), shape)
                if values is not None:
                    self._save(layer, a, b, values)  # the cache then holds what the run used
            if values is not None:
                self._store(layer, a, b, values)
            else:
                todo.append((a, b, shape))
        if todo:
            E = self.E_lo + self.h * np.arange(self.nE)
            tasks, pending = [], {}
            for a, b, shape in todo:
                ia, jb = self._tile_nodes(a), self._tile_nodes(b)
                pending[(a, b)] = [np.empty(shape), 0]
                if layer == "intact":
                    tasks.append(((a, b, None, None), (1.0, 1.0), E[ia], E[jb]))
                else:
                    for case in (WARP_WEAKER, FILL_WEAKER):
                        for k, r in enumerate(self.r_grid[:-1]):
                            # The r = 0 node holds the limit r -> 0+, solved at R_LIMIT: forces
                            # within 1e-4 of the broken cell's, and the weak yarn's stretch is
                            # its limit (a removed yarn has none), which the damage iteration needs.
                            r = max(r, R_LIMIT)
                            alpha = (r, 1.0) if case == WARP_WEAKER else (1.0, r)
                            tasks.append(((a, b, case, k), alpha, E[ia], E[jb]))
            n_solves = sum(len(t[2]) * len(t[3]) for t in tasks)
            bar = Progress(n_solves, f"surrogate: {len(todo)} {layer} tile(s)", self.progress)
            for (a, b, case, k), out in solve_blocks(tasks, self.fabric.to_dict(), self.n_elements,
                                                     self.workers, bar):
                entry = pending[(a, b)]
                if case is None:
                    entry[0][...] = out
                else:
                    entry[0][case, :, :, k, :] = out
                entry[1] += 1
                expected = 1 if case is None else 2 * (nr - 1)
                if entry[1] == expected:
                    self._store(layer, a, b, entry[0])
                    self._save(layer, a, b, entry[0])
            self.solves += n_solves
        self.build_seconds += time.perf_counter() - t0

    def _save(self, layer: str, a: int, b: int, values: np.ndarray) -> None:
        """Write a solved tile to the cache; if it cannot be written (read-only, full disk),
        keep it in memory only, stop writing and say so once."""
        path = self._tile_path(layer, a, b)
        if path is None or not self.cache_writable:
            return
        try:
            save_tile(path, self.key, values, self._tile_name(layer, a, b))
        except OSError as err:
            self.cache_writable = False
            warn_unwritable(f"{path.parent} cannot be written ({err.strerror or err})")

    def _store(self, layer: str, a: int, b: int, values: np.ndarray) -> None:
        ia, jb = self._tile_nodes(a), self._tile_nodes(b)
        sl = (slice(ia[0], ia[-1] + 1), slice(jb[0], jb[-1] + 1))
        if layer == "intact":
            self.intact[sl] = values
        else:
            self.damaged[(slice(None),) + sl + (slice(0, self.r_nodes - 1),)] = values
            self.damaged[(slice(None),) + sl + (self.r_nodes - 1,)] = self.intact[sl][None]
        self.built[layer][a, b] = True
        self._refresh_ready(layer)
        self._update_coefficients(layer, ia[0] - 2, ia[-1] + 2, jb[0] - 2, jb[-1] + 2)

    def _update_coefficients(self, layer: str, i0: int, i1: int, j0: int, j1: int) -> None:
        """Per-cell polynomial coefficients C_pq (value = sum C_pq t1^p t2^q) of the cells
        [i0, i1] x [j0, j1] whose taps touch a changed tile (cells beside an unbuilt tile
        hold NaN and are never looked up)."""
        first, last = interp.cell_range(self.order, self.nE)
        i0, i1 = max(i0, first), min(i1, last)
        j0, j1 = max(j0, first), min(j1, last)
        if i0 > i1 or j0 > j1:
            return
        M = interp.power_matrix(self.order)
        offsets = interp.TAPS[self.order]
        if layer == "intact":
            V = np.moveaxis(self.intact, -1, 0)  # (nq, nE, nE)
            F = np.stack([np.stack([V[:, i0 + oa:i1 + 1 + oa, j0 + ob:j1 + 1 + ob] for ob in offsets])
                          for oa in offsets])
            self._coef["intact"][i0:i1 + 1, j0:j1 + 1] = np.einsum("ap,bq,abxij->ijxpq", M, M, F,
                                                                    optimize=True)
            mu = F[:, :, [_Q["mu1"], _Q["mu2"]]]  # (taps, taps, 2, ni, nj)
        else:
            V = np.moveaxis(self.damaged, -1, 0)  # (nq, 2, nE, nE, nr)
            F = np.stack([np.stack([V[:, :, i0 + oa:i1 + 1 + oa, j0 + ob:j1 + 1 + ob] for ob in offsets])
                          for oa in offsets])
            self._coef["damaged"][:, i0:i1 + 1, j0:j1 + 1] = np.einsum("ap,bq,abxcijr->cijrxpq",
                                                                       M, M, F, optimize=True)
            mu = F[:, :, [_Q["mu1"], _Q["mu2"]]].max(axis=(3, 6))  # worst case over both cases and r
        limit = (self.mu_safe - MU_MARGIN)[None, None, :, None, None]
        with np.errstate(invalid="ignore"):  # NaN beside unbuilt tiles counts as unsafe
            self._safe[layer][i0:i1 + 1, j0:j1 + 1] = np.all(mu < limit, axis=(0, 1, 2))
        self._mu_top[layer][i0:i1 + 1, j0:j1 + 1] = np.moveaxis(mu.max(axis=(0, 1)), 0, -1)

    def build(self, layers=("intact", "damaged"), E1_range=None, E2_range=None) -> None:
        """Solve every tile of ``layers`` covering the strain ranges (default: the whole table)."""
        lo, hi = self.E_table
        idx = []
        for rng in (E1_range or (lo, hi), E2_range or (lo, hi)):
            i0 = int(np.clip(math.floor((rng[0] - self.E_lo) / self.h) - 1, 0, self.nE - 1))
            i1 = int(np.clip(math.ceil((rng[1] - self.E_lo) / self.h) + 2, 0, self.nE - 1))
            idx.append(range(i0 // self.tile, i1 // self.tile + 1))
        for layer in layers:
            self.ensure_tiles(layer, [(a, b) for a in idx[0] for b in idx[1]])

    def _cells(self, E1, E2) -> Cells:
        """Interpolation cells (i, j) and local coordinates (t1, t2) of the points."""
        i, t1 = interp.locate(E1, self.E_lo, self.h, self.nE, self.order)
        j, t2 = interp.locate(E2, self.E_lo, self.h, self.nE, self.order)
        return Cells(i, j, t1, t2)

    def _require(self, layer: str, i, j) -> None:
        """Build the tiles that the interpolation taps of cells (i, j) touch."""
        missing = ~self._ready[layer][i, j]
        if not missing.any():
            return
        i, j = i[missing], j[missing]
        lo, span, t = self._taps[0], self._taps[1], self.tile
        built = self.built[layer]
        touched = np.zeros_like(built)
        for a in ((i - lo) // t, (i - lo + span) // t):
            for b in ((j - lo) // t, (j - lo + span) // t):
                touched[a, b] = True
        self.ensure_tiles(layer, [tuple(p) for p in np.argwhere(touched & ~built)])

    def _refresh_ready(self, layer: str) -> None:
        """Cells whose interpolation taps all lie in built tiles (see :meth:`_require`)."""
        lo, span = self._taps
        k = np.arange(self.nE)
        first = np.minimum(np.maximum(k - lo, 0) // self.tile, self.n_tiles - 1)
        last = np.minimum(np.maximum(k - lo + span, 0) // self.tile, self.n_tiles - 1)
        b = self.built[layer]
        self._ready[layer] = (b[np.ix_(first, first)] & b[np.ix_(first, last)]
                              & b[np.ix_(last, first)] & b[np.ix_(last, last)])

    # ------------------------------------------------------------------ inputs
    def _inputs(self, E1, E2, a1, a2, names=("alpha1", "alpha2")):
        arrays = [np.asarray(x, dtype=float) for x in (E1, E2, a1, a2)]
        if any(x.shape != arrays[0].shape for x in arrays):
            arrays = [np.array(x) for x in np.broadcast_arrays(*arrays)]  # writeable copies
        E1, E2, a1, a2 = (np.ascontiguousarray(x).ravel() for x in arrays)
        if not E1.size:
            return E1, E2, a1, a2, arrays[0].shape
        E, alpha = np.empty((2, E1.size)), np.empty((2, E1.size))
        counts, ranges = np.zeros(5, np.int64), np.empty((2, 2))
        lo, hi = self.E_table
        interp_kernel.prepare_inputs(E1, E2, a1, a2, self.E_fail, lo, hi, E, alpha, counts, ranges)
        if counts[4]:
            self._reject(E1, E2, a1, a2, names)
        st = self.stats
        st.points += E1.size
        interp_kernel.record_inputs(counts, ranges, st.beyond_failure, st.compression, st.E_min, st.E_max)
        return E[0], E[1], alpha[0], alpha[1], arrays[0].shape

    @staticmethod
    def _reject(E1, E2, a1, a2, names):
        """Raise ValueError naming the first bad input point (NaN propagates through min/max)."""
        for label, x in (("E1", E1), ("E2", E2), (names[0], a1), (names[1], a2)):
            bad = ~np.isfinite(x)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise ValueError(f"surrogate input {label} has {int(bad.sum())} non-finite value(s), "
                                 f"first at point {k}: {label}={x[k]}, E1={E1[k]}, E2={E2[k]}")
        for label, x in ((names[0], a1), (names[1], a2)):
            bad = (x < 0) | (x > 1)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise ValueError(f"surrogate input {label} must lie in [0, 1]; point {k} has {x[k]}")
        bad = np.flatnonzero((E1 <= -0.5) | (E2 <= -0.5))
        if bad.size:
            k = int(bad[0])
            raise ValueError(f"strain at point {k} (E1={E1[k]}, E2={E2[k]}) is not a Green-Lagrange "
                             f"strain of a positive stretch (needs E > -0.5)")
        raise ValueError(f"surrogate inputs out of range: E1 in [{E1.min()}, {E1.max()}], "
                         f"E2 in [{E2.min()}, {E2.max()}]")

    # ------------------------------------------------------------------ interpolation
    def lookup(self, E1, E2, a1, a2, quantities=("P1", "P2", "mu1", "mu2"), derivative=False):
        """Raw table values (npts, len(quantities)) at frozen damage (alpha1, alpha2): forces
        and Psi scaled by alpha_max (damage scaling), signed (not tension-only), with the
        derivatives d/dE1 and d/dE2 when ``derivative``. The hot-path access for solvers:
        1-D float arrays inside ``E_table`` and alphas in [0, 1] are expected and not
        checked (:meth:`evaluate` checks its inputs). Quantities: any of ``QUANTITIES``.

        Points at r = alpha_min / alpha_max = 1 use the 2D intact layer; the others the
        damaged layer, linear in sqrt(r). Each cell's interpolant is a polynomial in the
        local coordinates, evaluated from its precomputed coefficients by the compiled
        :func:`interp_kernel.lookup`; tiles not built yet are solved first."""
        out, d1, d2, _ = self._lookup(E1, E2, a1, a2, tuple(quantities), derivative)
        return (out, d1, d2) if derivative else out

    def _values(self, E1, E2, a1, a2, quantities):
        """:meth:`lookup`'s values and per point whether its damage may change (True) or not
        (False: every table node its interpolation uses, all r, has both stretches at least
        MU_MARGIN below mu_crit)."""
        out, _, _, flag = self._lookup(E1, E2, a1, a2, tuple(quantities), False)
        return out, flag.astype(bool)

    def _lookup(self, E1, E2, a1, a2, quantities, derivative):
        E1, E2, a1, a2 = (np.ascontiguousarray(x, dtype=float) for x in (E1, E2, a1, a2))
        spec = self._spec(quantities)
        out = np.empty((E1.size, len(quantities)))
        d1, d2 = (np.empty_like(out), np.empty_like(out)) if derivative else (out, out)
        flag = np.empty(E1.size, np.int8)
        if derivative:
            interp_kernel.lookup_derivatives(E1, E2, a1, a2, self._table(), spec, out, d1, d2, flag)
        else:
            interp_kernel.lookup(E1, E2, a1, a2, self._table(), spec, out, flag)
        missing = np.flatnonzero(flag == 2)
        if missing.size:
            sub = [x[missing] for x in (E1, E2, a1, a2)]
            self._require_points(*sub)
            parts = self._lookup(*sub, quantities, derivative)
            for whole, part in zip((out, d1, d2, flag), parts):
                whole[missing] = part
        return out, d1, d2, flag

    def _table(self):
        """The tables and cell maps as :func:`interp_kernel.lookup` takes them."""
        first, last = interp.cell_range(self.order, self.nE)
        return (self._coef["intact"].reshape(-1), self._coef["damaged"].reshape(-1),
                self._ready["intact"], self._ready["damaged"], self._safe["intact"],
                self._safe["damaged"], self.E_lo, self.h, first, last, self.r_nodes,
                len(QUANTITIES), ALPHA_BROKEN, self.order + 1)

    def _spec(self, quantities):
        """:func:`interp_kernel.lookup`'s description of ``quantities``."""
        spec = self._kernel_quantities.get(quantities)
        if spec is None:
            dead = [np.full(len(quantities), np.nan) for _ in range(2)]
            for i in range(2):
                for c, q in enumerate(quantities):
                    if q == f"P{i + 1}":
                        dead[i][c] = 0.0
                    elif q == f"mu{i + 1}":
                        dead[i][c] = self.mu_complete[i]
            spec = (np.array([_Q[q] for q in quantities], dtype=np.int64),
                    np.array([not q.startswith("mu") for q in quantities]), dead[0], dead[1])
            self._kernel_quantities[quantities] = spec
        return spec

    def _require_points(self, E1, E2, a1, a2) -> None:
        """Build the tiles the points' look-ups need: the intact layer's, and the damaged
        layer's where the two yarns' integrities differ."""
        cells = self._cells(E1, E2)
        self._require("intact", cells.i, cells.j)
        damaged = np.flatnonzero(np.minimum(a1, a2) < np.maximum(a1, a2))
        if damaged.size:
            self._require("damaged", cells.i[damaged], cells.j[damaged])

    # ------------------------------------------------------------------ public API
    def evaluate(self, E1, E2, alpha1, alpha2, tension_only: bool = True):
        """P1, P2 (N/m) and mu1, mu2 with damage frozen at (alpha1, alpha2), vectorised."""
        E1, E2, a1, a2, shape = self._inputs(E1, E2, alpha1, alpha2)
        vals = self.lookup(E1, E2, a1, a2)
        P1, P2, mu1, mu2 = (vals[:, k].reshape(shape) for k in range(4))
        if tension_only:
            P1, P2 = np.maximum(P1, 0.0), np.maximum(P2, 0.0)
        return P1, P2, mu1, mu2

    def update(self, E1, E2, alpha1_hist, alpha2_hist, return_mu: bool = False,
               tension_only: bool = True, tol: float = 1e-10, crack_band=None,
               critical_stretch=None, softening_scale=None):
        """Constitutive update: P1, P2 (N/m) and the new alpha1, alpha2 [, mu1, mu2].

        alpha_i = min(alpha_i^hist, alpha(mu_i^max(alpha))) (Eq. 2-25, appendix A.1) is solved
        per point by the unit cell's bracketing iteration (:mod:`fabric_fenicsx.material.damage_solver`,
        compiled by :mod:`fabric_fenicsx.surrogate.kernels.damage`). Points whose stretch leaves their
        damage unchanged (mu_i below mu_i^crit, or unloading) take no iteration.

        The update always returns, with 0 <= alpha_i <= alpha_i^hist: a point whose fast
        iteration does not converge is finished by the iteration's guaranteed bracketing, and
        one with no root even there (a jump of the interpolated target larger than ACCEPT) gets
        the upper end of its final bracket (narrower than ``tol``). Both kinds are kept in
        ``self.damage_fallbacks`` (:class:`~fabric_fenicsx.material.damage_solver.FallbackLog`:
        counts and the first states); the first point without a root also gives a warning that
        names its state. Raises SurrogateError only for a non-finite table value (a fault of a
        table tile, not of the point).

        crack_band: None (the damage law as it is) or (scale1, scale2), each a scalar or an array
        shaped like E1, in (0, 1]: per point and yarn the crack-band scale s of the softening
        branch, alpha_i = alpha(mu_crit + (mu_i - mu_crit) / s)
        (:func:`fabric_fenicsx.material.fibril.crack_band_alpha`).

        critical_stretch, softening_scale: None or per yarn a scalar or an array like E1: each
        point's own mu_i^crit and softening scale s_i > 0 (a strength scatter's field,
        :func:`~fabric_fenicsx.material.scatter.point_laws`), within the ``damage_range``.
        """
        E1, E2, a1h, a2h, shape = self._inputs(E1, E2, alpha1_hist, alpha2_hist,
                                                ("alpha1_hist", "alpha2_hist"))
        band = np.ones((E1.size, 2))
        if crack_band is not None:
            for i in range(2):
                band[:, i] = np.broadcast_to(np.asarray(crack_band[i], float), shape).ravel()
            if not np.all((band > 0.0) & (band <= 1.0)):
                bad = band[~((band > 0.0) & (band <= 1.0))]
                raise ValueError(f"crack_band scales must lie in (0, 1], got {bad.flat[0]!r}")
        mu_crit = self.mu_crit[None].repeat(E1.size, axis=0)   # a third of a broadcast store's time
        if critical_stretch is not None or softening_scale is not None:
            point_laws(self.fabric.damage, critical_stretch, softening_scale, shape, mu_crit, band,
                       self.mu_safe, self.mu_complete)
        top = (self._mu_top["intact"], self._mu_top["damaged"]) if critical_stretch is not None else None
        P, alpha, residual, status, self.last_damaging = self._update_points(E1, E2, a1h, a2h, tol,
                                                                             band, mu_crit, top)
        # status != 0 (not converged) only where a point iterated: no status to look at when none did
        if (unsettled := self.last_damaging and status.any()) and np.any(status == damage_kernel.NON_FINITE):
            k = int(np.flatnonzero(status == damage_kernel.NON_FINITE)[0])
            raise SurrogateError(
                f"surrogate table: a non-finite stretch in the table tile of E1 = {E1[k]!r}, "
                f"E2 = {E2[k]!r} (alpha_hist = ({a1h[k]!r}, {a2h[k]!r})) stopped the damage "
                f"iteration; the tile is corrupt: delete the cache folder {self.cache_dir} to "
                f"rebuild it")
        fallback = np.flatnonzero((status == BRACKETED) | (status == UNCONVERGED)) if unsettled else status[:0]
        if fallback.size:
            log = self.__dict__.setdefault("damage_fallbacks", FallbackLog())
            first_unconverged = log.unconverged == 0
            hist = np.stack((a1h, a2h), axis=1)
            log.record(status[fallback], E1[fallback], E2[fallback], hist[fallback],
                       alpha[fallback], residual[fallback])
            bad = fallback[status[fallback] == UNCONVERGED]
            if bad.size and first_unconverged:
                import warnings
                k = int(bad[0])
                warnings.warn(
                    f"surrogate damage iteration: no root of Eq. 2-25 at E1 = {E1[k]!r}, "
                    f"E2 = {E2[k]!r}, alpha_hist = ({a1h[k]!r}, {a2h[k]!r}) (the interpolated "
                    f"target jumps there); used alpha = {tuple(map(float, alpha[k]))} with "
                    f"alpha - target = {tuple(map(float, residual[k]))}. The run goes on; such "
                    f"points are counted in Surrogate.damage_fallbacks", RuntimeWarning,
                    stacklevel=2)
        if tension_only:
            np.maximum(P, 0.0, out=P)
        out = [P[:, 0].reshape(shape), P[:, 1].reshape(shape), alpha[:, 0].reshape(shape),
               alpha[:, 1].reshape(shape)]
        if return_mu:
            mu = self.lookup(E1, E2, alpha[:, 0], alpha[:, 1], ("mu1", "mu2"))
            out += [mu[:, 0].reshape(shape), mu[:, 1].reshape(shape)]
        return tuple(out)

    def _update_points(self, E1, E2, a1, a2, tol, band, mu_crit, mu_top=None):
        """:func:`damage_kernel.update` of the points (crack-band scales ``band``, (n, 2),
        critical stretches ``mu_crit``, (n, 2)),
        building the tiles it asks for: (P, alpha, residual, status, number of points that
        iterated)."""
        n = E1.size
        P, alpha = np.empty((n, 2)), np.empty((n, 2))
        residual, status = np.empty((n, 2)), np.empty(n, np.int8)
        iterated, waiting = damage_kernel.update(
            E1, E2, a1, a2, self._table(), self._spec(("P1", "P2")), self._spec(("mu1", "mu2")),
            self._law, mu_crit, band, 2 * ALPHA_BROKEN, tol, P, alpha, residual, status, mu_top,
            MU_MARGIN)
        if waiting:
            again = np.flatnonzero((status == damage_kernel.NEEDS_TILES)
                                   | (status == damage_kernel.NEEDS_DAMAGED_TILES))
            lookup = again[status[again] == damage_kernel.NEEDS_TILES]
            self._require_points(E1[lookup], E2[lookup], a1[lookup], a2[lookup])
            growing = again[status[again] == damage_kernel.NEEDS_DAMAGED_TILES]
            cells = self._cells(E1[growing], E2[growing])
            self._require("damaged", cells.i, cells.j)  # every r (and the intact layer)
            *parts, more = self._update_points(E1[again], E2[again], a1[again], a2[again], tol,
                                               band[again], mu_crit[again], mu_top)
            for whole, part in zip((P, alpha, residual, status), parts):
                whole[again] = part
            iterated += more
        return P, alpha, residual, status, iterated

    def tangent(self, E1, E2, alpha1, alpha2):
        """dP_i/dlambda_j (N/m) with damage frozen, as arrays (dP1/dl1, dP1/dl2, dP2/dl1, dP2/dl2)."""
        E1, E2, a1, a2, shape = self._inputs(E1, E2, alpha1, alpha2)
        _, d1, d2 = self.lookup(E1, E2, a1, a2, ("P1", "P2"), derivative=True)
        return tuple(x.reshape(shape) for x in lambda_tangent(E1, E2, d1, d2))

    def zero_force_strain(self, yarn: int, E_other, lo, hi, a1, a2, guess=None,
                          tol: float = 1e-15, max_iter: int = 60):
        """Per point the strain x in [lo, hi] of ``yarn`` (1 warp, 2 fill) where its signed
        force P_yarn vanishes at frozen damage (a1, a2), the crossing yarn at E_other, for the
        points where P_yarn(lo) < 0. Newton's method inside the bracket, compiled
        (:func:`interp_kernel.zero_force_strain`), from ``guess`` where it lies inside the
        bracket (e.g. the last step's root), else from hi. ``tol`` 1e-15: Newton's last step
        ends at round-off, so a simple root does not depend on where the search started
        (measured over 1e5 random states, starts at the root +- 1e-6 and +- 1e-3 against hi:
        1.4e-17 for the fill; for the warp too, but for 11 of 56678 states, a warp at alpha 0.1
        with the fill stretched by 1.5e-4, where the interpolant crosses zero three times within
        2e-3 of strain, |P| < 270 N/m, and the start picks the root); bisection alone would
        take 48 steps from a bracket of 0.15.
        Returns (x, status): status ``interp_kernel.ROOT_FOUND``, ``ROOT_TENSION`` (P(lo) >= 0:
        x = lo) or ``ROOT_NONE`` (P(hi) < 0 too: x = lo). Tiles along [lo, hi] are built when
        the search needs them."""
        guess = np.full(np.size(lo), np.nan) if guess is None else guess
        E_other, lo, hi, guess, a1, a2 = (np.ascontiguousarray(v, dtype=float)
                                          for v in (E_other, lo, hi, guess, a1, a2))
        x, status = np.empty(lo.size), np.empty(lo.size, np.int8)
        waiting = interp_kernel.zero_force_strain(yarn - 1, E_other, lo, hi, guess, a1, a2, self._table(),
                                                  self._spec((f"P{yarn}",)), tol, max_iter, x, status)
        if waiting:   # searches that met a tile not built yet
            missing = np.flatnonzero(status == interp_kernel.ROOT_NEEDS_TILES)
            steps = int(np.ceil(float(np.max(hi[missing] - lo[missing])) / self.h)) + 2
            s = np.linspace(0.0, 1.0, steps)
            own = (lo[missing, None] + s * (hi[missing] - lo[missing])[:, None]).ravel()
            other = np.repeat(E_other[missing], steps)
            pts = (own, other) if yarn == 1 else (other, own)
            self._require_points(*pts, np.repeat(a1[missing], steps), np.repeat(a2[missing], steps))
            x[missing], status[missing] = self.zero_force_strain(
                yarn, E_other[missing], lo[missing], hi[missing], a1[missing], a2[missing],
                guess[missing], tol, max_iter)
        return x, status

    def constitutive_update(self, E1, E2, state):
        """:class:`~fabric_fenicsx.material.contract.MaterialLaw`: (P1, P2, new DamageState),
        P_i signed as the unit cell gives them (Eq. 2-31), alpha_i from Eq. 2-25 (:meth:`update`)."""
        P1, P2, a1, a2 = self.update(E1, E2, state.alpha1, state.alpha2, tension_only=False)
        return P1, P2, DamageState(a1, a2)

    def wave_modulus(self, E1, E2, state):
        """:class:`~fabric_fenicsx.material.contract.MaterialLaw`: per point the largest
        eigenvalue (N/m) of the symmetric part of dP_i/dlambda_j at frozen damage (the unit
        cell's signed tangent; the membrane's own rules are in ``fem.yarn_stress``)."""
        return symmetric_eigmax(*self.tangent(E1, E2, state.alpha1, state.alpha2))

    def respond(self, E1: float, E2: float, alpha_hist=(1.0, 1.0)):
        """A material-point result like :meth:`UnitCell.respond` (signed P, for static scenes)."""
        P1, P2, a1, a2, mu1, mu2 = self.update(E1, E2, alpha_hist[0], alpha_hist[1], return_mu=True,
                                               tension_only=False)
        V = self.lookup(*self._inputs(E1, E2, a1, a2)[:4], quantities=("V",))[0, 0]
        return SimpleNamespace(E1=float(E1), E2=float(E2), P1=float(P1), P2=float(P2), V=float(V),
                               alpha1=float(a1), alpha2=float(a2), mu1_max=float(mu1), mu2_max=float(mu2))

    def report_range(self) -> str:
        return self.stats.report(self.E_table[0])

    def describe(self) -> str:
        built = {k: int(v.sum()) for k, v in self.built.items()}
        return (f"surrogate {self.key}: h = {self.h:g}, r nodes = {self.r_nodes}, order = {self.order}, "
                f"E in [{self.E_table[0]:g}, {self.E_table[1]:g}] ({self.nE} nodes per axis with ghosts), "
                f"tiles built {built} of {self.n_tiles ** 2} per layer "
                f"({self.shipped.used if self.shipped else 0} of them shipped), cache {self.cache_dir}")


def lambda_tangent(E1, E2, dE1, dE2):
    """dP_i/dlambda_j = dP_i/dE_j lambda_j (E_j = (lambda_j^2 - 1)/2) from the columns (P1, P2)
    of :meth:`Surrogate.lookup`'s derivatives ``dE1``, ``dE2``: (dP1/dl1, dP1/dl2, dP2/dl1, dP2/dl2)."""
    l1, l2 = np.sqrt(1 + 2 * E1), np.sqrt(1 + 2 * E2)
    return dE1[:, 0] * l1, dE2[:, 0] * l2, dE1[:, 1] * l1, dE2[:, 1] * l2


def symmetric_eigmax(t11, t12, t21, t22):
    """Largest eigenvalue of the symmetric part of the 2 x 2 tangent [[t11, t12], [t21, t22]]
    per point: the wave modulus (N/m) of a tangent dP_i/dlambda_j."""
    b = 0.5 * (t12 + t21)
    return 0.5 * (t11 + t22) + np.sqrt(0.25 * (t11 - t22) ** 2 + b * b)


def material_point(fabric: Fabric, **settings) -> Surrogate:
    """A surrogate used as a material point of the static scenes (``--via surrogate``): its
    :meth:`Surrogate.respond` gives signed stresses, so the free-fill root find can see P2 < 0."""
    return Surrogate(fabric, **settings)

