"""Static material-point scenes of the thesis, chapter 3 (Figures 3-1 to 3-6).

One material point of the fabric is driven along a strain path; at each step the unit cell
(or any other *material point*, see :class:`MaterialPoint`) returns the membrane stresses
P_i = F_i / (2 w_j) (Eq. 2-31) with damage alpha_i = min(alpha_i^hist, alpha(mu_i^max))
(Eq. 2-25/A.12) carried from step to step. The scenes, named as in the project's issue:

* ``uniaxial-strain``  scenario 1, E2 = 0, E1 up to complete failure of the warp (Fig. 3-1);
* ``load-unload``      scenario 2, E2 = 0, load to E1 = 0.054 (partial warp damage), unload
  to E1 = 0, reload to complete failure (Fig. 3-2);
* ``equibiaxial``      scenario 3, E1 = E2 up to complete failure of both yarns (Fig. 3-3);
* ``uniaxial-stress``  scenario 4, P2 = 0 (fill free), E2 solved at each E1 (Figs. 3-4, 3-5);
* ``bending``          section 3.3.5, scenario 4 with the fill's bending stiffness B2 at the
  upper and at the lower bound of Table 1 (Fig. 3-6).

Monotone paths run on the grid E1 = k * step until every loaded yarn has failed completely,
then ``EXTRA_STEPS`` more; they stop at ``E1_CAP`` at the latest (reported). Nothing here
imports DOLFINx. The command line (``fabric-fenicsx static``) is :mod:`fabric_fenicsx.cli.static`.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from fabric_fenicsx.material.contract import DamageState, MaterialPoint
from fabric_fenicsx.material.fabric import Fabric, zylon_as
from fabric_fenicsx.material.unitcell import ALPHA_BROKEN, UnitCell

SCENARIOS = ("uniaxial-strain", "load-unload", "equibiaxial", "uniaxial-stress", "bending")
COLUMNS = ("E1", "E2", "P1", "P2", "alpha1", "alpha2", "V")
"""CSV columns of every scene (SI: P in N/m, V in N); load-unload adds ``leg``, bending ``B2``."""

DEFAULT_STEP = 0.0005
E1_CAP = 0.15
"""Hard cap on E1: a path that has not failed completely by then stops and says so."""
EXTRA_STEPS = 5
"""Steps recorded after complete failure, to show the flat tail."""
UNLOAD_E1 = 0.054
"""Unloading point of scenario 2: past the P1 peak (E1 ~ 0.049), warp partially damaged."""
BENDING_RATIO = 5.0
"""Upper / lower bound of the yarn bending stiffness (section 3.2, after Warren)."""
E2_MIN = -0.45
"""Lower end of the E2 search in the free-fill root find (E > -0.5 for any stretch)."""
LEGS = ("load", "unload", "reload")
MAX_STEPS = 200_000
"""Default limit on a scene's E1 steps (material-point solves; :func:`estimate_steps`). One step
takes about 15-20 ms on one core (measured, unit cell), so this is about an hour; the default
step gives a few hundred steps, and a step below ~1e-6 resolves nothing the figures show."""
PROGRESS_INTERVAL = 1.0
"""Wall seconds between progress lines."""

_LOADED = {  # yarns whose complete failure ends a monotone path (0 = warp, 1 = fill)
    "uniaxial-strain": (0,), "load-unload": (0,), "equibiaxial": (0, 1),
    "uniaxial-stress": (0,), "bending": (0,),
}
_TITLES = {
    "uniaxial-strain": "Scenario 1: uniaxial strain, E2 = 0",
    "load-unload": "Scenario 2: load, unload, reload, E2 = 0",
    "equibiaxial": "Scenario 3: equibiaxial strain, E1 = E2",
    "uniaxial-stress": "Scenario 4: uniaxial stress, P2 = 0",
    "bending": "Scenario 4 with B2 at its upper and lower bound",
}


# ----------------------------------------------------------------------------- material points
class UnitCellPoint:
    """The yarn unit cell (:class:`~fabric_fenicsx.material.unitcell.UnitCell`) as a material point."""

    supports_free_fill = True
    label = "unit cell"

    def __init__(self, fabric: Fabric, n_elements: int | None = None):
        self.cell = UnitCell(fabric, n_elements=n_elements)

    def respond(self, E1, E2, alpha_hist=(1.0, 1.0)):
        return self.cell.respond(E1, E2, alpha_hist=alpha_hist)

    def constitutive_update(self, E1, E2, state: DamageState):
        """:class:`~fabric_fenicsx.material.contract.MaterialLaw`, one unit-cell solve per point:
        (P1, P2, new DamageState), P_i signed as the unit cell gives them (Eq. 2-31)."""
        E1, E2 = np.atleast_1d(E1).astype(float), np.atleast_1d(E2).astype(float)
        rs = [self.respond(e1, e2, (a1, a2)) for e1, e2, a1, a2
              in zip(E1, E2, np.atleast_1d(state.alpha1), np.atleast_1d(state.alpha2))]
        P1, P2, a1, a2 = (np.array([getattr(r, k) for r in rs]) for k in ("P1", "P2", "alpha1", "alpha2"))
        return P1, P2, DamageState(a1, a2)

    def wave_modulus(self, E1, E2, state: DamageState, dlam: float = 1e-6):
        """:class:`~fabric_fenicsx.material.contract.MaterialLaw`: per point the largest
        eigenvalue (N/m) of the symmetric part of dP_i/dlambda_j at frozen damage, by central
        differences of the unit cell's solve in the stretches (4 solves per point)."""
        from fabric_fenicsx.surrogate.table import symmetric_eigmax

        def P(e1, e2, alpha):
            r = self.cell.solve(e1, e2, alpha=alpha)
            return np.array([r.P1, r.P2])

        E1, E2 = np.atleast_1d(E1).astype(float), np.atleast_1d(E2).astype(float)
        out = np.empty(E1.size)
        for k, (e1, e2, a1, a2) in enumerate(zip(E1, E2, np.atleast_1d(state.alpha1),
                                                np.atleast_1d(state.alpha2))):
            lam = np.sqrt(1.0 + 2.0 * np.array([e1, e2]))
            cols = []
            for j in range(2):
                step = np.zeros(2)
                step[j] = dlam
                Ep, Em = 0.5 * ((lam + step) ** 2 - 1.0), 0.5 * ((lam - step) ** 2 - 1.0)
                cols.append((P(*Ep, (a1, a2)) - P(*Em, (a1, a2))) / (2.0 * dlam))
            (t11, t21), (t12, t22) = cols
            out[k] = symmetric_eigmax(t11, t12, t21, t22)
        return out


def surrogate_point(fabric: Fabric):
    """The unit-cell surrogate as a material point (imported only when asked for)."""
    from fabric_fenicsx.surrogate.table import material_point
    return material_point(fabric)


BACKENDS: dict[str, Callable[[Fabric], MaterialPoint]] = {
    "unitcell": UnitCellPoint,
    "surrogate": surrogate_point,
}


def _factory(backend) -> Callable[[Fabric], MaterialPoint]:
    """Turn the ``backend`` argument of :func:`run_scenario` into a factory fabric -> point."""
    if backend is None:
        return UnitCellPoint
    if isinstance(backend, str):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {sorted(BACKENDS)}, got {backend!r}")
        return BACKENDS[backend]
    if not isinstance(backend, type) and hasattr(backend, "respond"):
        def same(fabric, _point=backend):
            return _point
        same.single = True
        return same
    if callable(backend):
        return backend
    raise ValueError(f"backend must be None, a name in {sorted(BACKENDS)}, a material point with "
                     f"respond(E1, E2, alpha_hist) or a factory fabric -> material point; got {backend!r}")


def _label(point) -> str:
    return str(getattr(point, "label", type(point).__name__))


def respond_free_fill(point, E1: float, alpha_hist, E2_guess: float = 0.0,
                      search_step: float = 2.5e-4, xtol: float = 1e-12, subdivisions: int = 8):
    """Response at E1 with the fill free (P2 = 0, scenario 4) for any material point.

    E2 is a root of P2(E1, E2; alpha_hist) = 0, the first one met marching from ``E2_guess``
    against the sign of P2 (P2 grows with E2 while the yarns are intact), with a step that
    starts at ``search_step`` and doubles up to 0.05. Near the warp's complete failure P2(E2)
    is not monotone (it jumps where the warp breaks, and a second root lies on the broken
    branch), so a step that moves P2 away from zero is re-sampled at ``subdivisions`` points
    before the march goes on: a narrow root next to the guess is not stepped over. The
    bracket is closed by Brent's method to ``xtol`` in E2. A fill that carries no force at
    all (P2 = 0 at the guess, e.g. a broken fill) keeps the guess. Damage evolves from
    ``alpha_hist`` at every trial E2, so the returned state is that of the root.
    """
    from scipy.optimize import brentq

    trials = {}

    def p2(E2):
        E2 = float(E2)
        r = point.respond(E1, E2, alpha_hist)
        value = float(r.P2)
        if not math.isfinite(value):
            raise FloatingPointError(f"material point returned P2 = {value} at E1 = {E1}, "
                                     f"E2 = {E2}, alpha_hist = {tuple(alpha_hist)}")
        trials[E2] = r
        return value

    def fail(E2, P2):
        return RuntimeError(
            f"free fill: no E2 with P2 = 0 between E2 = {E2_guess:.6g} (P2 = {f_guess:.6g} N/m) "
            f"and E2 = {E2:.6g} (P2 = {P2:.6g} N/m) at E1 = {E1:.6g}, alpha_hist = "
            f"{tuple(alpha_hist)}; the material point's P2 must change sign in E2")

    a = float(E2_guess)
    fa = f_guess = p2(a)
    if fa == 0.0:
        return trials[a]
    direction = -1.0 if fa > 0.0 else 1.0
    h = float(search_step)
    bracket = None
    while bracket is None:
        if (direction < 0 and a <= E2_MIN) or abs(a - E2_guess) > 1.0:
            raise fail(a, fa)
        b = max(a + direction * h, E2_MIN)
        fb = p2(b)
        if (fb > 0.0) != (fa > 0.0) or fb == 0.0:
            bracket = (a, fa, b)
        elif (fb - fa) * direction <= 0.0:  # P2 moved away from zero: look inside the step
            x_prev, f_prev = a, fa
            for x in a + (b - a) * np.arange(1, subdivisions) / subdivisions:
                fx = p2(x)
                if (fx > 0.0) != (f_prev > 0.0) or fx == 0.0:
                    bracket = (x_prev, f_prev, x)
                    break
                x_prev, f_prev = x, fx
        a, fa, h = b, fb, min(2.0 * h, 0.05)
    lo, f_lo, hi = bracket
    if trials[hi].P2 == 0.0:
        return trials[hi]
    root = brentq(p2, min(lo, hi), max(lo, hi), xtol=xtol)
    r = trials[root] if root in trials else point.respond(E1, root, alpha_hist)
    scale = max(abs(f_lo), abs(float(trials[hi].P2)))
    if abs(float(r.P2)) > 1e-6 * scale:
        raise RuntimeError(f"free fill: P2 jumps from {f_lo:.6g} to {float(trials[hi].P2):.6g} N/m "
                           f"between E2 = {lo:.8g} and {hi:.8g} at E1 = {E1:.6g} without a root "
                           f"(left P2 = {float(r.P2):.6g} N/m at E2 = {root:.8g}); try a smaller step")
    return r


# ----------------------------------------------------------------------------- results
@dataclass
class ScenarioResult:
    """A static scene: its rows (``data``, one array per column) and its key points.

    ``reference`` holds, for load-unload only, the monotone E2 = 0 path on the same grid
    (the "first loading" continued, against which reloading is compared).
    """

    name: str
    fabric: Fabric
    step: float
    backend: str
    columns: tuple[str, ...]
    data: dict[str, np.ndarray]
    key_points: dict = field(default_factory=dict)
    reference: dict[str, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self.data["E1"])

    def select(self, column: str, value) -> dict[str, np.ndarray]:
        """The rows whose ``column`` equals ``value`` (e.g. one leg, one B2)."""
        keep = self.data[column] == value
        return {k: v[keep] for k, v in self.data.items()}


class _Recorder:
    """Collects rows; with a CSV path writes and flushes each row as it comes."""

    def __init__(self, columns, csv_path=None, progress=False, label="", expected=None):
        self.columns = tuple(columns)
        self.expected = expected  # upper bound of the rows (estimate_steps), for the progress
        self.rows: dict[str, list] = {c: [] for c in self.columns}
        self.file = None
        if csv_path is not None:
            self.file = open(csv_path, "w", encoding="utf-8", newline="")
            self.file.write(",".join(self.columns) + "\n")
            self.file.flush()
        self.progress = progress
        self.label = label
        self.t0 = self.t_last = time.perf_counter()

    def add(self, **row) -> None:
        for c in self.columns:
            self.rows[c].append(row[c])
        if self.file is not None:
            self.file.write(",".join(v if isinstance(v, str) else f"{v:.12g}"
                                     for v in (row[c] for c in self.columns)) + "\n")
            self.file.flush()
        now = time.perf_counter()
        if self.progress and now - self.t_last >= PROGRESS_INTERVAL:
            self.t_last = now
            print(f"{self.label}: E1 = {row['E1']:.4f}, alpha = ({row['alpha1']:.3f}, "
                  f"{row['alpha2']:.3f}), {self._done(now)}", file=sys.stderr, flush=True)

    def _done(self, now: float) -> str:
        """Rows done (of at most ``expected``, with the time left at most) and seconds so far."""
        n, elapsed = len(self.rows["E1"]), now - self.t0
        if not self.expected:
            return f"{n} rows, {elapsed:.1f} s"
        left = elapsed / n * max(self.expected - n, 0) if n else 0.0
        return (f"{n} of at most {self.expected} steps ({100 * n / self.expected:.0f} %), "
                f"{elapsed:.1f} s, at most {left:.0f} s left")

    def arrays(self) -> dict[str, np.ndarray]:
        return {c: np.array(v, dtype=object) if c == "leg" else np.asarray(v, dtype=float)
                for c, v in self.rows.items()}

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None


def _row(r, E1: float) -> dict:
    row = {"E1": float(E1), "E2": float(r.E2), "P1": float(r.P1), "P2": float(r.P2),
           "alpha1": float(r.alpha1), "alpha2": float(r.alpha2), "V": float(r.V)}
    bad = {k: v for k, v in row.items() if not math.isfinite(v)}
    if bad:
        raise FloatingPointError(f"material point returned non-finite {bad} at E1 = {E1:.6g}, "
                                 f"E2 = {row['E2']:.6g}; try a smaller --step")
    return row


# ----------------------------------------------------------------------------- paths
def _grid(step: float, insert=()):
    """E1 = 0, step, 2 step, ... (no accumulated rounding) merged with the ``insert`` points."""
    extra = sorted(float(x) for x in insert)
    k = 0
    while True:
        E1 = float(f"{k * step:.12g}")  # 0.0295, not 0.029500000000000002, in CSV and JSON
        while extra and extra[0] < E1 - 1e-12:
            yield extra.pop(0)
        if extra and abs(extra[0] - E1) <= 1e-12:
            E1 = extra.pop(0)
        yield E1
        k += 1


class _Driver:
    """Steps one material point along E1 with E2 given by ``mode`` and damage carried over."""

    def __init__(self, point, mode: str, step: float):
        self.point = point
        self.mode = mode  # "zero" (E2 = 0), "equal" (E2 = E1) or "free" (P2 = 0)
        self.step = step
        self.alpha = (1.0, 1.0)
        self.free_native = bool(getattr(point, "supports_free_fill", False))
        self.E2_hist: list[tuple[float, float]] = []

    def __call__(self, E1: float) -> dict:
        if self.mode == "zero":
            r = self.point.respond(E1, 0.0, self.alpha)
        elif self.mode == "equal":
            r = self.point.respond(E1, E1, self.alpha)
        elif self.free_native:
            r = self.point.respond(E1, None, self.alpha)
        else:
            r = respond_free_fill(self.point, E1, self.alpha, self._guess(E1),
                                  search_step=min(0.25 * self.step, 2.5e-4))
        row = _row(r, E1)
        self.alpha = (row["alpha1"], row["alpha2"])
        self.E2_hist = (self.E2_hist + [(E1, row["E2"])])[-2:]
        return row

    def _guess(self, E1: float) -> float:
        if len(self.E2_hist) < 2:
            return self.E2_hist[-1][1] if self.E2_hist else 0.0
        (x0, y0), (x1, y1) = self.E2_hist
        return y1 + (y1 - y0) / (x1 - x0) * (E1 - x1) if x1 != x0 else y1


def _monotone(driver: _Driver, values, loaded, add) -> bool:
    """Run E1 over ``values`` until the loaded yarns fail (+ EXTRA_STEPS); True if capped."""
    extra_left = None
    for E1 in values:
        if E1 > E1_CAP + 1e-12:
            return True
        row = driver(E1)
        add(row)
        if extra_left is None:
            if all(row[f"alpha{i + 1}"] <= ALPHA_BROKEN for i in loaded):
                extra_left = EXTRA_STEPS
                if extra_left == 0:
                    return False
        else:
            extra_left -= 1
            if extra_left == 0:
                return False
    return False


# ----------------------------------------------------------------------------- key points
def _first(E1, mask):
    idx = np.flatnonzero(mask)
    return float(E1[idx[0]]) if idx.size else None


def _peaks(E1, P, min_prominence=0.05):
    """Local maxima of P (interior or at the end of the path) with prominence >= fraction of max."""
    from scipy.signal import find_peaks

    if P.size == 0 or np.max(P) <= 0.0:
        return []
    padded = np.concatenate(([-np.inf], P, [-np.inf]))
    idx, _ = find_peaks(padded, prominence=min_prominence * float(np.max(P)))
    return [{"E1": float(E1[i - 1]), "P": float(P[i - 1])} for i in idx]


def path_key_points(data: dict[str, np.ndarray]) -> dict:
    """Peak of P1 (and every prominent local peak of P1 and P2), damage onset (first E1 with
    alpha_i < 1) and complete failure (first E1 with alpha_i <= ALPHA_BROKEN) for each yarn."""
    E1, P1, P2 = data["E1"], data["P1"], data["P2"]
    i = int(np.argmax(P1))
    kp = {
        "peak_P1": {"E1": float(E1[i]), "P1": float(P1[i])},
        "peaks_P1": [{"E1": p["E1"], "P1": p["P"]} for p in _peaks(E1, P1)],
        "peaks_P2": [{"E1": p["E1"], "P2": p["P"]} for p in _peaks(E1, P2)],
        "damage_onset": {}, "complete_failure": {}, "E1_max": float(E1[-1]),
    }
    if np.max(P2) > 0.0:
        j = int(np.argmax(P2))
        kp["peak_P2"] = {"E1": float(E1[j]), "P2": float(P2[j])}
    for k, yarn in ((1, "warp"), (2, "fill")):
        a = data[f"alpha{k}"]
        kp["damage_onset"][yarn] = _first(E1, a < 1.0 - 1e-12)
        kp["complete_failure"][yarn] = _first(E1, a <= ALPHA_BROKEN)
    return kp


def _free_fill_key_points(data) -> dict:
    """Scenario 4: the largest transverse contraction (where E2 turns back, Fig. 3-5)."""
    alive = data["alpha1"] > ALPHA_BROKEN
    E2 = np.where(alive, data["E2"], np.inf)
    j = int(np.argmin(E2))
    return {"E2_min": {"E1": float(data["E1"][j]), "E2": float(data["E2"][j])}}


def _interp_P1(data, E1):
    E, P = data["E1"], data["P1"]
    return float(np.interp(E1, E, P)) if E[0] <= E1 <= E[-1] else None


# ----------------------------------------------------------------------------- scenarios
def check_step(step) -> float:
    """``step`` as a float, or a ValueError unless it is a finite number in (0, E1_CAP]."""
    try:
        s = float(step)
    except (TypeError, ValueError):
        raise ValueError(f"step must be a positive number, got {step!r}") from None
    if not math.isfinite(s) or s <= 0.0 or s > E1_CAP:
        raise ValueError(f"step must be a finite number in (0, {E1_CAP}], got {step!r}")
    return s


def estimate_steps(name: str, fabric: Fabric | None, step: float, unload_at: float = UNLOAD_E1) -> int:
    """An upper bound of the E1 steps (material-point solves) scene ``name`` takes at ``step``,
    known before it runs: its CSV rows plus, for load-unload, the reference monotone path.

    A monotone path (:func:`_path_steps`) ends EXTRA_STEPS after the loaded yarns' complete
    failure. load-unload adds its load and unload legs to unload_at and the reference path;
    bending runs two paths. The bound is about 1.4 times the steps taken for Zylon AS."""
    path = _path_steps(name, fabric, step)
    if name == "load-unload":
        leg = math.floor(unload_at / step + 1e-9) + 2  # the grid and unload_at itself
        return leg + (leg - 1) + 2 * path
    return 2 * path if name == "bending" else path


def _path_steps(name: str, fabric: Fabric | None, step: float) -> int:
    """Steps of one monotone path, at most: complete failure of the loaded yarns comes at the
    latest at the first grid point at or beyond E1 = E_fail = ((mu_complete L / w)^2 - 1) / 2
    (a yarn is at least as stretched as its projection, lambda w / L; mu_complete from the
    damage law; the crimp is pulled out before, so the path ends earlier), then EXTRA_STEPS
    more; and at E1_CAP in any case."""
    base = zylon_as("max") if fabric is None else fabric
    law = base.damage
    E_fail = [0.5 * ((law.mu_complete(y.mu_crit) * y.L / y.w) ** 2 - 1.0) for y in base.yarns]
    E_end = max(E_fail[i] for i in _LOADED[name])
    return min(math.ceil(E_end / step - 1e-9) + EXTRA_STEPS, math.floor(E1_CAP / step + 1e-9)) + 1


def check_budget(name: str, fabric: Fabric | None, step: float, max_steps: int | None = MAX_STEPS,
                 unload_at: float = UNLOAD_E1) -> int:
    """:func:`estimate_steps`, or a ValueError if it exceeds ``max_steps`` (None: no limit) that
    gives the estimate, its time and the smallest step within the limit."""
    n = estimate_steps(name, fabric, step, unload_at)
    if max_steps is not None and n > max_steps:
        smallest = step * n / max_steps
        raise ValueError(
            f"--step {step:g}: scene {name} would take up to {n:,} steps (material-point solves), "
            f"about {_duration(n * 0.018)} at ~18 ms each, more than the limit of {max_steps:,}; "
            f"use --step {_round_up(smallest)} or larger (default {DEFAULT_STEP:g}), or raise the limit "
            f"with --max-steps")
    return n


def _duration(seconds: float) -> str:
    """``seconds`` in the largest unit that gives at least 2 of it."""
    for unit, size in (("days", 86400.0), ("hours", 3600.0), ("minutes", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.0f} {unit}"
    return f"{seconds:.0f} s"


def _round_up(x: float) -> str:
    """``x`` rounded up to two significant digits, as text."""
    exponent = math.floor(math.log10(x)) - 1
    return f"{math.ceil(x / 10.0 ** exponent - 1e-9) * 10.0 ** exponent:.2g}"


def bending_bounds(fabric: Fabric | None = None) -> tuple[float, float]:
    """Upper and lower bound of the fill's bending stiffness B2 (N m^2) for the bending scene.

    Table 1 of the thesis (``fabric=None``, Zylon AS); for another fabric its fill's B0 is the
    upper bound and B0 / BENDING_RATIO the lower (section 3.2: "five times the minimum").
    """
    if fabric is None:
        return zylon_as("max").fill.B0, zylon_as("min").fill.B0
    return fabric.fill.B0, fabric.fill.B0 / BENDING_RATIO


def run_scenario(name: str, fabric: Fabric | None = None, step: float = DEFAULT_STEP,
                 backend=None, progress: bool = True, csv_path=None,
                 unload_at: float = UNLOAD_E1,
                 fill_B0_bounds: tuple[float, float] | None = None,
                 max_steps: int | None = MAX_STEPS) -> ScenarioResult:
    """Run one static scene on one material point (thesis section 3.3).

    Parameters
    ----------
    name : one of ``SCENARIOS``.
    fabric : the fabric (default: Zylon AS, Table 1, bending stiffness at the upper bound).
        For ``bending`` it provides the warp; the fill's B0 takes both ``fill_B0_bounds``.
    step : E1 increment (> 0; the issue asks for 0.0005 or finer).
    backend : None or "unitcell" (the unit cell), "surrogate", a factory fabric -> material
        point, or a material point itself (:class:`MaterialPoint`; not for ``bending``, which
        needs one per B2).
    progress : report progress on stderr about once a second.
    csv_path : if given, rows are written there as they are computed (flushed each row).
    unload_at : E1 at which ``load-unload`` unloads.
    fill_B0_bounds : (upper, lower) fill bending stiffness (N m^2) of ``bending``; default
        :func:`bending_bounds` of the given fabric (Table 1 if ``fabric`` is None).
    max_steps : refuse (ValueError, before any solve) a ``step`` whose :func:`estimate_steps`
        exceeds this; None = no limit.

    Returns a :class:`ScenarioResult`; its ``key_points`` are those of :func:`path_key_points`
    plus, per scene, ``cap_reached``, the unloading checks or the per-B2 results.
    """
    if name not in SCENARIOS:
        raise ValueError(f"scenario must be one of {', '.join(SCENARIOS)}; got {name!r}")
    step = check_step(step)
    make = _factory(backend)
    if name == "bending" and getattr(make, "single", False):
        raise ValueError("the bending scene needs one material point per fill bending stiffness: "
                         "pass a factory fabric -> material point (or a backend name) as backend")
    base = zylon_as("max") if fabric is None else fabric
    if not isinstance(base, Fabric):
        raise ValueError(f"fabric must be a Fabric, got {fabric!r}")
    expected = check_budget(name, base, step, max_steps, unload_at)
    if name == "load-unload":  # the reference path is not recorded
        expected -= _path_steps(name, base, step)
    extra_cols = {"load-unload": ("leg",), "bending": ("B2",)}.get(name, ())
    rec = _Recorder(COLUMNS + extra_cols, csv_path, progress, name, expected)
    loaded = _LOADED[name]
    kp: dict = {"scenario": name}
    reference = None
    try:
        if name in ("uniaxial-strain", "equibiaxial", "uniaxial-stress"):
            point = make(base)
            mode = {"uniaxial-strain": "zero", "equibiaxial": "equal", "uniaxial-stress": "free"}[name]
            capped = _monotone(_Driver(point, mode, step), _grid(step), loaded,
                               lambda row: rec.add(**row))
            data = rec.arrays()
            kp.update(path_key_points(data))
            if name == "uniaxial-stress":
                kp.update(_free_fill_key_points(data))
            kp["cap_reached"] = capped
        elif name == "load-unload":
            point = make(base)
            data, reference, extra = _load_unload(point, make, base, step, unload_at, loaded, rec)
            # Key points of the loading envelope: first loading, then reloading past unload_at.
            envelope = ((data["leg"] == "load")
                        | ((data["leg"] == "reload") & (data["E1"] > unload_at + 1e-12)))
            kp.update(path_key_points({k: v[envelope] for k, v in data.items()}))
            kp.update(extra)
        else:
            bounds = bending_bounds(fabric) if fill_B0_bounds is None else fill_B0_bounds
            point, data, extra = _bending(make, base, bounds, step, loaded, rec)
            kp.update(extra)
    finally:
        rec.close()
    kp.update({"fabric": base.name, "backend": _label(point), "step": step})
    return ScenarioResult(name=name, fabric=base, step=step, backend=_label(point),
                          columns=rec.columns, data=data, key_points=kp, reference=reference)


def _load_unload(point, make, fabric, step, unload_at, loaded, rec):
    if not (isinstance(unload_at, (int, float)) and 0.0 < unload_at < E1_CAP):
        raise ValueError(f"unload_at must lie in (0, {E1_CAP}), got {unload_at!r}")
    driver = _Driver(point, "zero", step)
    load = []
    for E1 in _grid(step, insert=(unload_at,)):
        if E1 > unload_at + 1e-12:
            break
        load.append(E1)
    for E1 in load:
        rec.add(leg="load", **driver(E1))
    alpha_unload = driver.alpha
    for E1 in reversed(load[:-1]):
        rec.add(leg="unload", **driver(E1))
    capped = _monotone(driver, _grid(step, insert=(unload_at,)), loaded,
                       lambda row: rec.add(leg="reload", **row))
    data = rec.arrays()
    # The monotone path on the same grid ("first loading" continued) from a fresh point.
    ref_point = point if getattr(make, "single", False) else make(fabric)
    ref = _Recorder(COLUMNS)
    _monotone(_Driver(ref_point, "zero", step), _grid(step, insert=(unload_at,)), loaded,
              lambda row: ref.add(**row))
    reference = ref.arrays()

    legs = {leg: {k: v[data["leg"] == leg] for k, v in data.items()} for leg in LEGS}
    unload, reload = legs["unload"], legs["reload"]
    beyond = reload["E1"] >= unload_at - 1e-12
    dev = []
    for E1, P1 in zip(reload["E1"][beyond], reload["P1"][beyond]):
        j = np.flatnonzero(np.abs(reference["E1"] - E1) <= 1e-12)
        if j.size:
            dev.append(abs(P1 - reference["P1"][j[0]]))
    below = reload["E1"] < unload_at - 1e-12
    retrace = np.abs(reload["P1"][below] - np.interp(reload["E1"][below], unload["E1"][::-1],
                                                     unload["P1"][::-1]))
    extra = {
        "unload_at": {"E1": float(unload_at), "P1": float(legs["load"]["P1"][-1]),
                      "alpha1": float(alpha_unload[0]), "alpha2": float(alpha_unload[1])},
        "residual_P1_at_zero_strain": float(unload["P1"][-1]),
        "residual_P2_at_zero_strain": float(unload["P2"][-1]),
        "reload_max_deviation_P1": float(max(dev)) if dev else None,
        "reload_retrace_max_deviation_P1": float(retrace.max()) if retrace.size else None,
        "monotone_peak_P1": path_key_points(reference)["peak_P1"],
        "cap_reached": capped,
    }
    return data, reference, extra


def _bending(make, base, bounds, step, loaded, rec):
    upper, lower = (float(b) for b in bounds)
    if not (math.isfinite(lower) and 0.0 < lower < upper and math.isfinite(upper)):
        raise ValueError(f"fill_B0_bounds must be (upper, lower) with upper > lower > 0, got {bounds!r}")
    runs = {}
    point = None
    for bound, B2 in (("upper", upper), ("lower", lower)):
        point = make(base.with_yarn("fill", B0=B2))
        sub = _Recorder(COLUMNS)

        def add(row, sub=sub, B2=B2):
            rec.add(B2=B2, **row)
            sub.add(**row)

        capped = _monotone(_Driver(point, "free", step), _grid(step), loaded, add)
        d = sub.arrays()
        kp = {"B2": B2, **path_key_points(d), **_free_fill_key_points(d), "cap_reached": capped}
        runs[bound] = (d, kp)
    du, dl = runs["upper"][0], runs["lower"][0]
    E_peak = runs["upper"][1]["peak_P1"]["E1"]
    compare = {}
    for label, E1 in (("E1_0.01", 0.01), ("E1_0.02", 0.02), ("upper_peak", E_peak)):
        pu, pl = _interp_P1(du, E1), _interp_P1(dl, E1)
        if pu is not None and pl is not None and pu > 0:
            compare[label] = {"E1": E1, "P1_upper": pu, "P1_lower": pl, "ratio": pl / pu}
    extra = {"B2_upper": runs["upper"][1], "B2_lower": runs["lower"][1], "P1_lower_over_upper": compare,
             "cap_reached": runs["upper"][1]["cap_reached"] or runs["lower"][1]["cap_reached"]}
    return point, rec.arrays(), extra


# ----------------------------------------------------------------------------- report
def _fmt(E):
    return "-" if E is None else f"{E:.4f}"


def _path_lines(kp, indent="  ") -> list[str]:
    lines = [f"{indent}peak of P1: E1 = {kp['peak_P1']['E1']:.4f}, P1 = {kp['peak_P1']['P1'] / 1e3:.2f} kN/m"]
    if len(kp["peaks_P1"]) > 1:
        lines.append(indent + "peaks of P1: " + "; ".join(
            f"E1 = {p['E1']:.4f}, P1 = {p['P1'] / 1e3:.2f} kN/m" for p in kp["peaks_P1"]))
    if "peak_P2" in kp:
        pk = kp["peak_P2"]
        lines.append(f"{indent}peak of P2: E1 = {pk['E1']:.4f}, P2 = {pk['P2'] / 1e3:.2f} kN/m")
    for yarn in ("warp", "fill"):
        on, off = kp["damage_onset"][yarn], kp["complete_failure"][yarn]
        if on is None:
            lines.append(f"{indent}{yarn}: no damage up to E1 = {kp['E1_max']:.4f}")
        else:
            lines.append(f"{indent}{yarn}: damage onset at E1 = {_fmt(on)}, complete failure at "
                         f"E1 = {_fmt(off) if off is not None else '- (not reached)'}")
    if "E2_min" in kp:
        m = kp["E2_min"]
        lines.append(f"{indent}largest contraction: E2 = {m['E2']:.4f} at E1 = {m['E1']:.4f}")
    if kp.get("cap_reached"):
        lines.append(f"{indent}stopped at the cap E1 = {E1_CAP} before complete failure")
    return lines


def format_key_points(result: ScenarioResult) -> str:
    """The key points of a scene as printed by the command line."""
    kp = result.key_points
    head = f"{result.name} ({result.fabric.name}, {result.backend}, step {result.step:g}, {len(result)} rows)"
    lines = [head]
    if result.name == "bending":
        for bound in ("upper", "lower"):
            k = kp[f"B2_{bound}"]
            lines.append(f" B2 = {k['B2'] * 1e6:.4f} N mm^2 ({bound} bound):")
            lines += _path_lines(k)
        for label, c in kp["P1_lower_over_upper"].items():
            lines.append(f" P1(lower B2) / P1(upper B2) at E1 = {c['E1']:.4f}: {c['ratio']:.3f}")
        return "\n".join(lines)
    lines += _path_lines(kp)
    if result.name == "load-unload":
        u = kp["unload_at"]
        lines.append(f"  unloaded at E1 = {u['E1']:.4f} (P1 = {u['P1'] / 1e3:.2f} kN/m, "
                     f"alpha1 = {u['alpha1']:.4f})")
        lines.append(f"  residual P1 at zero strain: {kp['residual_P1_at_zero_strain']:.3g} N/m")
        dev = kp["reload_max_deviation_P1"]
        lines.append(f"  reload vs first loading beyond the unload point: max |dP1| = "
                     f"{'-' if dev is None else f'{dev:.3g}'} N/m")
    return "\n".join(lines)


def write_key_points(result: ScenarioResult, path) -> None:
    Path(path).write_text(json.dumps(result.key_points, indent=2) + "\n")


# ----------------------------------------------------------------------------- plot
def _alpha_axis(ax, data, style="--", lw=1.2, label_suffix=""):
    ax2 = ax.twinx()
    ax2.plot(data["E1"], data["alpha1"], "C0" + style, lw=lw, label="alpha1 (warp)" + label_suffix)
    ax2.plot(data["E1"], data["alpha2"], "C1" + style, lw=lw, label="alpha2 (fill)" + label_suffix)
    ax2.set_ylim(-0.05, 1.1)
    ax2.set_ylabel("damage parameter alpha (-)")
    return ax2


def plot_scenario(result: ScenarioResult, path) -> None:
    """PNG in the style of the thesis's Figs. 3-1 to 3-6: P1, P2 (kN/m) against E1 with alpha
    on a right axis; E2 against E1 as a second panel for scenario 4."""
    from matplotlib.figure import Figure

    name, d = result.name, result.data
    two_panels = name in ("uniaxial-stress", "bending")
    fig = Figure(figsize=(11, 4.5) if two_panels else (6.5, 4.5), layout="constrained")
    axes = fig.subplots(1, 2) if two_panels else [fig.subplots()]
    ax = axes[0]
    if name == "load-unload":
        ref = result.reference
        ax.plot(ref["E1"], ref["P1"] / 1e3, color="0.6", lw=0.8, ls=":", label="monotone loading")
        for leg, lw in (("load", 2.8), ("unload", 1.0), ("reload", 1.0)):
            s = result.select("leg", leg)
            ls = "-" if leg != "unload" else "--"
            ax.plot(s["E1"], s["P1"] / 1e3, "C0", lw=lw, ls=ls, label=f"P1, {leg}")
            ax.plot(s["E1"], s["P2"] / 1e3, "C1", lw=lw, ls=ls, label=f"P2, {leg}")
        ax2 = _alpha_axis(ax, d, style=":")
    elif name == "bending":
        kp = result.key_points
        for bound, ls in (("upper", "-"), ("lower", "--")):
            B2 = kp[f"B2_{bound}"]["B2"]
            s = result.select("B2", B2)
            tag = f"B2 = {B2 * 1e6:.4f} N mm^2 ({bound})"
            ax.plot(s["E1"], s["P1"] / 1e3, "C0", ls=ls, lw=1.8, label=f"P1, {tag}")
            axes[1].plot(s["E1"], s["E2"], "C2", ls=ls, lw=1.8, label=tag)
        ax2 = _alpha_axis(ax, result.select("B2", kp["B2_upper"]["B2"]), style=":",
                          label_suffix=", upper B2")
    else:
        ax.plot(d["E1"], d["P1"] / 1e3, "C0", lw=1.8, label="P1 (warp)")
        if name != "uniaxial-stress":
            ax.plot(d["E1"], d["P2"] / 1e3, "C1", lw=1.8, label="P2 (fill)")
        ax2 = _alpha_axis(ax, d)
        if name == "uniaxial-stress":
            axes[1].plot(d["E1"], d["E2"], "C2", lw=1.8, label="E2 (P2 = 0)")
    ax.set_xlabel("membrane strain E1 (-)")
    ax.set_ylabel("membrane stress P (kN/m)")
    ax.set_ylim(bottom=min(0.0, ax.get_ylim()[0]))
    ax.set_title(_TITLES[name], fontsize=10)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper left")
    if two_panels:
        axes[1].axhline(0.0, color="0.7", lw=0.6)
        axes[1].set_xlabel("membrane strain E1 (-)")
        axes[1].set_ylabel("membrane strain E2 (-)")
        axes[1].set_title("transverse strain with P2 = 0 (Fig. 3-5)", fontsize=10)
        axes[1].legend(fontsize=7)
    fig.suptitle(f"{result.fabric.name}, {result.backend}, step {result.step:g}", fontsize=8)
    fig.savefig(path, dpi=120)
