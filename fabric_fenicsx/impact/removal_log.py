"""Where removal happens and why: one record per removed cell, and what the run's removals add
up to.

Each cell :class:`~fabric_fenicsx.impact.removal.CellRemoval` takes out is recorded at the
moment it goes (:func:`removal_records`): the rule that removed it (``deletion``: every point
has both yarns broken, SDV1 = 0 of Table 2; ``erosion``: a yarn-direction Green strain beyond
``material.erosion_strain``, docs/impact_model.md), the time, each yarn's integrity (the
smallest alpha_i of Eq. 2-25 over the cell's points) and largest Green strain E_i (Eq. 2-3)
and stretch mu_i = sqrt(1 + 2 E_i) over its points, its reference centroid and its chord
along each yarn (:func:`chords_through_centroid`). The run writes them to ``removed_cells.csv``
(:data:`REMOVED_CELL_COLUMNS`) and sums them up in summary.json (:func:`removal_statistics`).
Recording reads the material's state; it changes nothing the run computes.
"""
from __future__ import annotations

import numpy as np

from fabric_fenicsx.fem.polygons import polygon_areas, polygon_centroids

__all__ = ["REMOVED_CELL_COLUMNS", "RULES", "BROKEN_BELOW", "FAMILY_STATES", "polygon_centroids",
           "chords_through_centroid", "corner_extents", "family_states", "removal_records",
           "removal_statistics", "polygon_areas"]

RULES = ("deletion", "erosion")
"""The removal rules, in the order of their code in :data:`REMOVED_CELL_COLUMNS`' ``rule``."""

REMOVED_CELL_COLUMNS = ("time_s", "rule", "cell", "x_m", "y_m", "alpha1_warp", "alpha2_fill",
                        "E1_max_warp", "E2_max_fill", "mu1_max_warp", "mu2_max_fill",
                        "chord1_warp_m", "chord2_fill_m")
"""removed_cells.csv, one row per removed cell in the order of removal (within a step: by rank,
then by the rank's cell number):

* ``time_s``: t_n of the step whose state removed it (the strains and damage evaluated at t_n,
  history.csv's time of that step);
* ``rule``: ``deletion`` or ``erosion`` (:data:`RULES`);
* ``cell``: the cell's global number (DOLFINx's cell index map; the local number on one rank);
* ``x_m``, ``y_m``: its reference area centroid (m);
* ``alpha1_warp``, ``alpha2_fill``: the smallest integrity alpha_i over its points (Eq. 2-25;
  1 intact, 0 broken; SDV2, SDV3 of Table 2);
* ``E1_max_warp``, ``E2_max_fill``: the largest yarn Green strain E_i over its points (Eq. 2-3);
* ``mu1_max_warp``, ``mu2_max_fill``: the same as stretches, mu_i = sqrt(1 + 2 E_i);
* ``chord1_warp_m``, ``chord2_fill_m``: the length (m) of the straight line through the centroid
  along the reference warp (fill) direction that lies inside the reference cell
  (:func:`chords_through_centroid`)."""

BROKEN_BELOW = 0.5
"""A yarn family of a removed cell counts as *broken* when its smallest integrity alpha_i is
below this (more than half of the yarn's strength lost): the family states of
:func:`family_states`. The CSV keeps both alphas, so other thresholds can be applied to it."""

FAMILY_STATES = ("warp_only", "fill_only", "both", "neither")
"""The yarn families broken (alpha_i < :data:`BROKEN_BELOW`) in a removed cell."""



def chords_through_centroid(corners: np.ndarray, direction: np.ndarray,
                            through: np.ndarray | None = None) -> np.ndarray:
    """Length of the straight line through a point of each convex polygon along ``direction``
    (a unit 2-vector) that lies inside the polygon, shape (n,): the cell's chord along a yarn.

    corners: (n, k, 2) in perimeter order (either sense); through: (n, 2) points inside the
    polygons (default: their area centroids, :func:`polygon_centroids`). The line c + t d is
    clipped by each edge's half-plane n_j . (c + t d - p_j) <= 0 (n_j the edge's outward
    normal, Cyrus-Beck clipping): t runs from the largest entry bound to the smallest exit bound,
    the chord is their difference. Exact for convex cells (every corner at a positive Jacobian,
    as the meshes here are)."""
    c = polygon_centroids(corners) if through is None else through
    p, q = corners, np.roll(corners, -1, axis=1)
    edge = q - p
    sense = np.sign(0.5 * (p[..., 0] * q[..., 1] - q[..., 0] * p[..., 1]).sum(axis=1))   # +1: counter-clockwise
    normal = np.stack([edge[..., 1], -edge[..., 0]], axis=-1) * sense[:, None, None]     # outward
    along = normal @ np.asarray(direction, dtype=float)                  # n_j . d, (n, k)
    room = ((p - c[:, None, :]) * normal).sum(axis=-1)                  # n_j . (p_j - c) >= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = room / along
    t_exit = np.where(along > 0, t, np.inf).min(axis=1)
    t_entry = np.where(along < 0, t, -np.inf).max(axis=1)
    return t_exit - t_entry


def corner_extents(corners: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Extent of each polygon's corners projected on ``direction`` (max - min of p . d), shape
    (n,): an upper bound of :func:`chords_through_centroid`, equal to it for a rectangle along
    the direction."""
    s = corners @ np.asarray(direction, dtype=float)
    return s.max(axis=1) - s.min(axis=1)


def family_states(alpha1: np.ndarray, alpha2: np.ndarray, broken_below: float = BROKEN_BELOW) -> np.ndarray:
    """Index into :data:`FAMILY_STATES` per cell: which yarn families are broken (alpha_i below
    ``broken_below``) in it."""
    warp, fill = np.asarray(alpha1) < broken_below, np.asarray(alpha2) < broken_below
    return np.select([warp & ~fill, fill & ~warp, warp & fill], [0, 1, 2], default=3)


def removal_records(time: float, rule: np.ndarray, cells: np.ndarray, global_cells: np.ndarray,
                    alpha1: np.ndarray, alpha2: np.ndarray, E1: np.ndarray, E2: np.ndarray,
                    n_points_per_cell: int, centroids: np.ndarray, chords: np.ndarray) -> np.ndarray:
    """The rows of :data:`REMOVED_CELL_COLUMNS` (``rule`` as its index in :data:`RULES`) for the
    cells ``cells`` of this rank removed at ``time`` by the rules ``rule``, from the point
    values alpha_i, E_i (cell-major, ``n_points_per_cell`` each) of the material's last update;
    shape (cells.size, len(REMOVED_CELL_COLUMNS)). ``centroids`` (n_cells, 2) and ``chords``
    (n_cells, 2: warp, fill) are those of every owned cell."""
    points = cells[:, None] * n_points_per_cell + np.arange(n_points_per_cell)
    a1, a2 = np.asarray(alpha1)[points].min(axis=1), np.asarray(alpha2)[points].min(axis=1)
    e1, e2 = np.asarray(E1)[points].max(axis=1), np.asarray(E2)[points].max(axis=1)
    return np.column_stack([np.full(cells.size, float(time)), rule, global_cells[cells],
                            centroids[cells], a1, a2, e1, e2, np.sqrt(1.0 + 2.0 * e1),
                            np.sqrt(1.0 + 2.0 * e2), chords[cells]]).astype(float)


def removal_statistics(rows: np.ndarray, broken_below: float = BROKEN_BELOW) -> dict:
    """What the removed cells ``rows`` (:func:`removal_records`, every rank's) add up to:
    counts per rule and per family state (:func:`family_states`), both together, the first
    removal time per family state (s; None if none) and the median chord (m) per yarn of the
    removed cells, over all and per rule (None without removed cells)."""
    rows = np.asarray(rows, dtype=float).reshape(-1, len(REMOVED_CELL_COLUMNS))
    col = {c: i for i, c in enumerate(REMOVED_CELL_COLUMNS)}
    rule = rows[:, col["rule"]].astype(int)
    state = family_states(rows[:, col["alpha1_warp"]], rows[:, col["alpha2_fill"]], broken_below)
    t = rows[:, col["time_s"]]
    chords = rows[:, [col["chord1_warp_m"], col["chord2_fill_m"]]]

    def median_chords(mask):
        if not mask.any():
            return {"warp": None, "fill": None}
        med = np.median(chords[mask], axis=0)
        return {"warp": float(med[0]), "fill": float(med[1])}

    return {
        "broken_below_alpha": broken_below,
        "cells": int(rows.shape[0]),
        "by_rule": {r: int(np.count_nonzero(rule == i)) for i, r in enumerate(RULES)},
        "by_family_state": {s: int(np.count_nonzero(state == j)) for j, s in enumerate(FAMILY_STATES)},
        "by_rule_and_family_state": {r: {s: int(np.count_nonzero((rule == i) & (state == j)))
                                         for j, s in enumerate(FAMILY_STATES)}
                                     for i, r in enumerate(RULES)},
        "first_removal_time_s": {s: (float(t[state == j].min()) if np.any(state == j) else None)
                                 for j, s in enumerate(FAMILY_STATES)},
        "median_chord_m": median_chords(np.ones(rule.size, dtype=bool)),
        "median_chord_by_rule_m": {r: median_chords(rule == i) for i, r in enumerate(RULES)},
    }
