"""The speed of the first stress wave along the warp and along the fill (docs/validation.md;
thesis Sec. 4.3: "the stress wave runs faster along the less crimped fill yarns").

A short run of XY0 (warp along x) on a uniform mesh along the yarns writes its displacement
every microsecond; along the warp axis through the impact point (the nodes on y = 0, x > 0)
and along the fill axis (x = 0, y > 0) the front is the farthest node that has moved along the
axis by more than ``threshold`` of the largest such displacement on that axis in that frame.
The speed is the slope of a straight line fitted to the front's position against time while the
front is between 10 % and 80 % of the half-width. The expected speed of each yarn's longitudinal
wave is sqrt(K_i / rho_A), K_i = dP_i / dlambda_i of the unit cell at zero strain (the table's
tangent) and rho_A the fabric's areal density.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["RUN_SETTINGS", "front_positions", "fit_speed", "wave_speeds", "expected_speeds"]

RUN_SETTINGS = ("mesh.kind=uniform", "mesh.n=136", "material.damage=false", "run.t_end=2.5e-5",
                "output.xdmf_interval=1e-6", "output.png=false", "projectile.velocity=57.3")
"""The run the speeds are measured on (with the XY0 scene): 2 mm squares along the yarns (an even number: a node at the centre), 25 us."""


def front_positions(s: np.ndarray, u: np.ndarray, threshold: float = 0.01) -> np.ndarray:
    """Per frame, the largest distance s of a node whose displacement along the axis exceeds
    ``threshold`` x the largest on the axis in that frame (nan where the largest is below 1e-3
    of the largest of all frames: nothing has moved yet).
    s: (n,) distances of the axis nodes from the impact point; u: (frames, n)."""
    out = np.full(u.shape[0], np.nan)
    a = np.abs(u)
    floor = 1e-3 * a.max()       # frames before the projectile touches move by round-off only
    for i, row in enumerate(a):
        peak = row.max()
        if peak > floor:
            out[i] = s[row > threshold * peak].max()
    return out


def fit_speed(t: np.ndarray, front: np.ndarray, half_width: float, lo: float = 0.1, hi: float = 0.8):
    """Least-squares slope (m/s) of the front's position against time while it lies between
    ``lo`` and ``hi`` of ``half_width``; None with fewer than 3 such frames."""
    ok = np.isfinite(front) & (front >= lo * half_width) & (front <= hi * half_width)
    if np.count_nonzero(ok) < 3:
        return None
    return float(np.polyfit(t[ok], front[ok], 1)[0])


def wave_speeds(out_dir: str | Path, threshold: float = 0.01) -> dict:
    """Measured warp and fill wave speeds of the run in ``out_dir`` (its impact.xdmf; warp along
    x): ``{"warp": m/s, "fill": m/s, "times": ..., "warp_front": ..., "fill_front": ...}``."""
    from fabric_fenicsx.impact.output import read_run

    frames = read_run(out_dir)
    t = np.asarray(frames.times)
    first = frames[0]
    X = np.asarray(first.points)[:, :2]
    half = 0.5 * (X[:, 0].max() - X[:, 0].min())
    tol = 1e-9 + 1e-6 * half
    axes = {"warp": (np.flatnonzero((np.abs(X[:, 1]) < tol) & (X[:, 0] > 0)), 0),
            "fill": (np.flatnonzero((np.abs(X[:, 0]) < tol) & (X[:, 1] > 0)), 1)}
    disp = np.array([np.asarray(f.point_data["displacement"])[:, :2] for f in frames])
    out = {"times": t.tolist()}
    for name, (nodes, comp) in axes.items():
        if nodes.size < 3:
            raise ValueError(f"{out_dir}: no mesh line along the {name} axis through the impact point "
                             "(the run needs a mesh along x and y with a node at the centre)")
        front = front_positions(X[nodes, comp], disp[:, nodes, comp], threshold)
        out[name] = fit_speed(t, front, half)
        out[f"{name}_front"] = front.tolist()
    return out


def expected_speeds(surrogate) -> dict:
    """sqrt(K_i / rho_A) for warp and fill, K_i the table's dP_i/dlambda_i at E = 0."""
    from fabric_fenicsx.surrogate.table import lambda_tangent

    one, zero = np.ones(1), np.zeros(1)
    _, d1, d2 = surrogate.lookup(zero, zero, one, one, ("P1", "P2"), derivative=True)
    k11, _, _, k22 = lambda_tangent(zero, zero, d1, d2)
    rho = surrogate.fabric.areal_density
    return {"warp": float(np.sqrt(k11[0] / rho)), "fill": float(np.sqrt(k22[0] / rho)),
            "K_warp": float(k11[0]), "K_fill": float(k22[0]), "areal_density": rho}
