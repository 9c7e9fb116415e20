"""Unit-cell benchmark: solve times along loading paths and convergence with element count.

Prints (not a test):
1. the median time of one warm-started unit-cell call along a path of small strain steps,
   for ``respond`` (damage evolving) and ``solve`` (damage frozen); target <= 1 ms;
2. the time of a 300-point scenario-1 path (E2 = 0) through damage to complete warp failure,
   and of ``run_scenario("uniaxial-strain")`` at the default step; target <= 1 s;
3. the convergence of P1, P2 and V with the number of linear elements per half-yarn,
   n = 4 .. 128 against n = 768, at E = (0.03, 0.01) (intact) and at E = (0.055, 0) on the
   damage branch (alpha1 evolving from 1; alpha1 compared as well), with observed orders
   log2(e_n / e_2n).

Run:  python3 benchmarks/bench_unitcell.py      (about 2 minutes: the n = 768 references)
"""
import statistics
import time

import numpy as np

from fabric_fenicsx.material.fabric import zylon_as
from fabric_fenicsx.studies.static import run_scenario
from fabric_fenicsx.material.unitcell import N_ELEMENTS_DEFAULT, UnitCell

FABRIC = zylon_as("max")


def median_call_ms(cell, method, E1_path, E2):
    times = []
    alpha = (1.0, 1.0)
    for E1 in E1_path:
        t0 = time.perf_counter()
        if method == "respond":
            r = cell.respond(float(E1), E2, alpha_hist=alpha)
            alpha = (r.alpha1, r.alpha2)
        else:
            cell.solve(float(E1), E2)
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times), 1e3 * max(times)


print(f"== warm-started calls (n = {N_ELEMENTS_DEFAULT} elements per half-yarn), E1 steps of 1e-4")
path = np.arange(1, 451) * 1e-4  # E1 up to 0.045: intact yarns, contact
for method in ("respond", "solve"):
    for E2, label in ((0.0, "E2 = 0"), (0.01, "E2 = 0.01"), (None, "P2 = 0 (E2 free)")):
        med, worst = median_call_ms(UnitCell(FABRIC), method, path, E2)
        print(f"  {method:7s} {label:17s} median {med:6.3f} ms   max {worst:6.2f} ms   (target <= 1 ms)")

print("== scenario-1 path through damage")
cell = UnitCell(FABRIC)
E1_path = np.linspace(0.0, 0.075, 300)
alpha = (1.0, 1.0)
t0 = time.perf_counter()
for E1 in E1_path:
    r = cell.respond(float(E1), 0.0, alpha_hist=alpha)
    alpha = (r.alpha1, r.alpha2)
t_path = time.perf_counter() - t0
print(f"  300 points, E1 = 0 .. 0.075, respond: {t_path:.3f} s (target <= 1 s), final alpha1 = {alpha[0]:.3g}")
t0 = time.perf_counter()
res = run_scenario("uniaxial-strain", progress=False)
print(f"  run_scenario('uniaxial-strain'), step 0.0005: {len(res)} points in {time.perf_counter() - t0:.3f} s")


def convergence(label, call, quantities):
    ns = [4, 8, 16, 32, 64, 128]
    t0 = time.perf_counter()
    ref = call(768)
    t_ref = time.perf_counter() - t0
    print(f"== convergence at {label}; reference n = 768 ({t_ref:.1f} s): "
          + ", ".join(f"{q} = {getattr(ref, q):.6g}" for q in quantities))
    print("    n  " + "  ".join(f"{'err ' + q:>11s} {'order':>5s}" for q in quantities))
    prev = None
    for n in ns:
        r = call(n)
        errs = [abs(getattr(r, q) - getattr(ref, q)) / abs(getattr(ref, q)) for q in quantities]
        cols = []
        for k, e in enumerate(errs):
            order = "" if prev is None or e == 0 else f"{np.log2(prev[k] / e):5.2f}"
            cols.append(f"{e:11.3e} {order:>5s}")
        print(f"  {n:4d}  " + "  ".join(cols))
        prev = errs


convergence("E = (0.03, 0.01), intact", lambda n: UnitCell(FABRIC, n_elements=n).solve(0.03, 0.01),
            ("P1", "P2", "V"))


def damaged(n):
    # Monotone loading: one respond from alpha_hist = (1, 1) reaches the same state as the
    # scenario-1 path (checked below at the default n), and is far cheaper at n = 768.
    return UnitCell(FABRIC, n_elements=n).respond(0.055, 0.0)


c = UnitCell(FABRIC)
alpha = (1.0, 1.0)
for E1 in np.arange(0, 111) * 0.0005:  # the scenario-1 path up to E1 = 0.055
    r = c.respond(float(E1), 0.0, alpha_hist=alpha)
    alpha = (r.alpha1, r.alpha2)
d = damaged(N_ELEMENTS_DEFAULT)
print(f"== damaged state E = (0.055, 0): path vs one respond at n = {N_ELEMENTS_DEFAULT}: "
      f"|dP1|/P1 = {abs(r.P1 - d.P1) / abs(r.P1):.1e}, |dalpha1| = {abs(r.alpha1 - d.alpha1):.1e}")
convergence("E = (0.055, 0), damaged warp", damaged, ("P1", "P2", "V", "alpha1"))
