"""Static material-point scenes of the thesis, chapter 3 (Figures 3-1 to 3-6).

One material point of the fabric is driven along a strain path; at each step the unit cell
(or any other *material point*, see :class:`MaterialPoint`) returns the membrane stresses
P_i = F_i / (2 w_j) (Eq. 2-31) with damage alpha_i = min(alpha_i^hist, alpha(mu_i^max))
(Eq. 2-25/A.12) carried from step to step. The scenes:

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

The code is split by concern; every name stays importable from this module:

* :mod:`.static_scenarios`: the scenes, the constants of their paths, the step budget;
* :mod:`.static_points`: the material points (unit cell, surrogate) and the free-fill response;
* this module: the runner (:func:`run_scenario`, the paths, the rows);
* :mod:`.static_report`: key points, printed summary, JSON and figure.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from fabric_fenicsx.material.contract import DamageState, MaterialPoint  # noqa: F401 - re-exported
from fabric_fenicsx.material.fabric import Fabric, zylon_as
from fabric_fenicsx.material.unitcell import ALPHA_BROKEN, UnitCell  # noqa: F401 - re-exported
from fabric_fenicsx.studies.static_points import (  # noqa: F401 - re-exported
    BACKENDS, E2_MIN, UnitCellPoint, _factory, _label, respond_free_fill, surrogate_point)
from fabric_fenicsx.studies.static_report import (  # noqa: F401 - re-exported
    _alpha_axis, _first, _fmt, _free_fill_key_points, _interp_P1, _path_lines, _peaks,
    format_key_points, path_key_points, plot_scenario, write_key_points)
from fabric_fenicsx.studies.static_scenarios import (  # noqa: F401 - re-exported
    _LOADED, _TITLES, BENDING_RATIO, COLUMNS, DEFAULT_STEP, E1_CAP, EXTRA_STEPS, LEGS, MAX_STEPS,
    SCENARIOS, UNLOAD_E1, _duration, _path_steps, _round_up, bending_bounds, check_budget,
    check_step, estimate_steps)

PROGRESS_INTERVAL = 1.0
"""Wall seconds between progress lines."""

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
