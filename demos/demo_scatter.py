"""The fabric's strength scatter (fabric_fenicsx.material.scatter): the random field on the yarns.

Every warp segment of a 40 x 40 mm patch of Zylon AS (a segment = one yarn between two
crossings, 0.73 mm) draws its critical stretch from the Weibull model (median = the thesis's
mu_crit, modulus 11.7, seed 0); the same field read by the unit cells (one segment each) and by
square cells of 1, 2 and 4 mm: each cell takes the weakest segment it covers (the rule that keeps a
strip's strength the same on every mesh, docs/mesh_independence.md section 10). Larger cells are
weaker on average and scatter less: a cell of n segments is their weakest link. No DOLFINx.

Run:  python3 demos/demo_scatter.py [output_dir]      (default output_dir: out/scatter)
Writes ``scatter_field.png`` (the field on the segments and on 1 and 4 mm cells) and
``scatter.csv`` (per cell size: mean and standard deviation of the warp critical strain).
"""
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fabric_fenicsx.material.fabric import zylon_as  # noqa: E402
from fabric_fenicsx.material.scatter import StrengthScatter, cell_laws  # noqa: E402

out_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/scatter")
out_dir.mkdir(parents=True, exist_ok=True)
fabric, scatter, side = zylon_as(), StrengthScatter("weibull", seed=0), 0.04
segment = 2 * fabric.warp.w      # a warp segment's length; warp yarns lie 2 w_fill apart


def square_cells(h):
    """n x n cells of side h from the origin's grid line (h = segment: the unit cells, 2 w1 x 2 w2)."""
    hx, hy = (2 * fabric.warp.w, 2 * fabric.fill.w) if h == segment else (h, h)
    n = int(round(side / h))
    X, Y = np.meshgrid((np.arange(n) - n // 2) * hx, (np.arange(n) - n // 2) * hy, indexing="ij")
    low = np.stack([X.ravel(), Y.ravel()], 1)
    return low[:, None, :] + np.array([[0, 0], [hx, 0], [hx, hy], [0, hy]]) * 1.0, n


rows, maps = [], {}
print(f"{'cells':>10s} {'count':>6s} {'mean strain':>12s} {'sd':>9s}")
for h in (segment, 1e-3, 2e-3, 4e-3):
    corners, n = square_cells(h)
    mu, _ = cell_laws(scatter, fabric, 0.0, corners)
    strain = mu[:, 0] - 1.0
    maps[h] = strain.reshape(n, n)
    rows.append({"cell_mm": 1e3 * h, "cells": strain.size, "mean_strain": strain.mean(), "sd_strain": strain.std(ddof=1)})
    print(f"{1e3 * h:8.3f}mm {strain.size:6d} {strain.mean():12.5f} {strain.std(ddof=1):9.5f}")
with open(out_dir / "scatter.csv", "w", newline="") as f:
    writer = csv.DictWriter(f, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)

fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
lo, hi = maps[segment].min(), maps[segment].max()
for ax, h in zip(axes, (segment, 1e-3, 4e-3)):
    im = ax.imshow(maps[h].T, origin="lower", extent=[-20, 20, -20, 20], vmin=lo, vmax=hi, cmap="magma")
    ax.set(title=f"warp critical strain, cells of {1e3 * h:.2f} mm", xlabel="x (mm), warp direction",
           ylabel="y (mm)")
fig.colorbar(im, ax=axes, shrink=0.8, label="mu_crit - 1")
fig.savefig(out_dir / "scatter_field.png", dpi=110)
print(f"median segment strain {np.median(maps[segment]):.5f} (thesis mu_crit - 1 = {fabric.warp.mu_crit - 1:.5f}); "
      f"wrote {out_dir / 'scatter_field.png'}")
