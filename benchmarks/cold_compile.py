"""Benchmark: numba's compile time on a cold first run (prints numbers; not a test).

Runs the demo of ``make demo`` (demos/scenes/y90.toml at 57.3 m/s, h_centre = 4 mm) in this
process with numba's on-disk cache pointed at a new empty folder (``NUMBA_CACHE_DIR``), so that
every kernel the run calls is compiled as on a fresh clone, and the surrogate's tile cache at
another (the shipped tiles are read). It prints, per compiled function, how long numba took to
compile it (inclusive of the functions it calls that were compiled with it, and without them),
how many signatures each kernel got, the run's wall time and the sum of the compile times.

    .venv/bin/python benchmarks/cold_compile.py [--warm] [--warmed] [--steps N] [--keep DIR]

``--warm``: run twice in the same numba cache folder (separate processes) and print the
second run's compile times too; ``--warmed``: run ``fabric_fenicsx.impact.warm``
(what ``make setup`` runs) in the empty cache first, and show what the demo still compiles;
``--steps N``: stop the demo after N steps (every kernel is called by step 14, where the first
compressed yarn calls the tension field's search); ``--keep DIR``: use DIR as the numba cache
folder and keep it.

numba's compile events (``numba.core.event``, "numba:compile") give the times; a function
compiled inside another's compile (a callee) is counted in both the inclusive time of its
caller and its own line, and once in the total.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEMO = ["impact", str(ROOT / "demos/scenes/y90.toml"), "--set", "projectile.velocity=57.3",
        "--set", "mesh.h_centre=0.004", "--quiet"]


def child(out: Path, steps: int | None) -> None:
    """Run the demo here, recording numba's compile events; write them to out/compile.json."""
    from numba.core import event

    stack, records, dispatchers = [], [], set()

    class Listener(event.Listener):
        def on_start(self, ev):
            stack.append([time.perf_counter(), 0.0])

        def on_end(self, ev):
            t0, inner = stack.pop()
            dt = time.perf_counter() - t0
            if stack:
                stack[-1][1] += dt
            disp = ev.data["dispatcher"]
            dispatchers.add(disp)
            records.append({"name": f"{disp.py_func.__module__}.{disp.py_func.__qualname__}",
                            "args": str(ev.data["args"]), "inclusive_s": dt, "own_s": dt - inner,
                            "top": not stack})

    event.register("numba:compile", Listener())
    from fabric_fenicsx.cli import main
    args = DEMO + ["--out", str(out / "run")]
    if steps:
        args += ["--set", f"run.max_steps={steps}"]
    t0 = time.perf_counter()
    main(args)
    wall = time.perf_counter() - t0
    llvm = {}
    for disp in dispatchers:
        name = f"{disp.py_func.__module__}.{disp.py_func.__qualname__}"
        for sig in disp.overloads:
            timers = disp.get_metadata(sig).get("timers", {}) if hasattr(disp, "get_metadata") else {}
            llvm[name] = llvm.get(name, 0.0) + timers.get("llvm_lock", 0.0)
    (out / "compile.json").write_text(json.dumps({"wall_s": wall, "records": records, "llvm": llvm}))


def report(data: dict, title: str) -> float:
    recs = data["records"]
    total = sum(r["inclusive_s"] for r in recs if r["top"])
    print(f"\n{title}: run {data['wall_s']:.1f} s, numba compiling {total:.1f} s "
          f"({len(recs)} compiles, {sum(r['top'] for r in recs)} at top level)")
    by = {}
    for r in recs:
        e = by.setdefault(r["name"], [0, 0.0, 0.0])
        e[0] += 1
        e[1] += r["inclusive_s"]
        e[2] += r["own_s"]
    llvm = data.get("llvm", {})
    print(f"  {'function':<62} {'sigs':>4} {'incl. s':>8} {'own s':>7} {'LLVM s':>7}")
    for name, (n, inc, own) in sorted(by.items(), key=lambda kv: -kv[1][1]):
        print(f"  {name:<62} {n:>4} {inc:8.2f} {own:7.2f} {llvm.get(name, 0.0):7.2f}")
    return total


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--warm", action="store_true")
    p.add_argument("--warmed", action="store_true")
    p.add_argument("--steps", type=int, default=None)
    p.add_argument("--keep", default=None)
    p.add_argument("--child", default=None, help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.child:
        child(Path(a.child), a.steps)
        return 0
    with tempfile.TemporaryDirectory(prefix="cold-compile-") as tmp:
        tmp = Path(tmp)
        numba_dir = Path(a.keep) if a.keep else tmp / "numba"
        env = dict(os.environ, NUMBA_CACHE_DIR=str(numba_dir), FABRIC_FENICSX_CACHE=str(tmp / "tiles"))
        if a.warmed:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "fabric_fenicsx.impact.warm"], env=env,
                           check=True)
            print(f"warm-up process {time.perf_counter() - t0:.1f} s")
        runs = ["warmed" if a.warmed else "cold"] + (["warm"] if a.warm else [])
        for name in runs:
            out = tmp / name
            out.mkdir()
            cmd = [sys.executable, __file__, "--child", str(out)]
            if a.steps:
                cmd += ["--steps", str(a.steps)]
            t0 = time.perf_counter()
            subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
            proc = time.perf_counter() - t0
            data = json.loads((out / "compile.json").read_text())
            report(data, f"{name} numba cache (process {proc:.1f} s)")
            summary = json.loads((out / "run" / "summary.json").read_text())
            print(f"  residual velocity {summary['residual_velocity']!r} m/s after {summary['n_steps']} steps")
    return 0


if __name__ == "__main__":
    sys.exit(main())
