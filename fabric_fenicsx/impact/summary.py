"""summary.json of an impact run: what the run computed, every key named for what it holds.

Deflections (m, > 0 along the impact, at the node nearest the impact point):
``max_deflection`` is the largest central deflection of the run; ``damage_onset_deflection`` the
deflection when the first yarn starts to break; ``first_removal_deflection`` when the first
cell goes. ``peak_deflection`` is the former name of ``max_deflection``, kept for one release.
Energies (J) are in ``energies``; the balance and its terms are explained in
docs/impact_model.md.
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.impact.chatter import chatter_statistics
from fabric_fenicsx.impact.ledger import reduce_named
from fabric_fenicsx.impact.removal_log import removal_statistics
from fabric_fenicsx.impact.setup import quadrature_degree
from fabric_fenicsx.provenance import code_fingerprint

__all__ = ["build_summary", "time_split"]


def time_split(sim) -> dict[str, float]:
    """Wall time (s) of the run by phase. The surrogate solves missing table tiles inside its
    lookups (constitutive update, dt checks, the energy of removed cells): that one-off cost is
    reported apart (``surrogate_tiles``, all of the run's) and taken out of the phase it was
    spent in."""
    timings, clock = dict(sim.cd.timings), sim.clock
    tiles = clock.tiles.get
    in_checks = tiles("dt_check", 0.0)
    return {"strain": timings["strain"], "constitutive": timings["material"] - tiles("step", 0.0),
            "assembly": timings["assembly"], "contact": clock.contact - tiles("contact", 0.0),
            "output": clock.output - tiles("output", 0.0), "integrator": timings["rest"],
            "dt_check": clock.dt_check - in_checks,
            "bookkeeping": clock.bookkeeping - clock.dt_check - (tiles("bookkeeping", 0.0) - in_checks),
            "surrogate_tiles": sim._tile_seconds() - sim._tile_seconds0}


def _surrogate_section(sim, diagnostics: dict[str, float]) -> dict | None:
    """The surrogate's key and resolution, its solves in this run and the material's counters
    of evaluations outside the table (summed over the ranks)."""
    counts = {"points_beyond_table_damage_off": diagnostics.get("beyond_table", 0),
              "points_compressed_below_table": diagnostics.get("below_table", 0),
              "points_slack_with_table_tension": diagnostics.get("slack_tension", 0),
              "wave_modulus_bounded": diagnostics.get("modulus_bounded", 0),
              "points_wrinkled": diagnostics.get("wrinkled", 0),
              "points_wrinkled_without_force_free_strain": diagnostics.get("wrinkled_without_root", 0)}
    counts = {k: int(v) for k, v in counts.items()}
    sur = sim.surrogate
    if sur is None:
        return {"key": None, **counts}
    return {"key": sur.key, "resolution": sur.h,
            "solves_this_run": sim.comm.allreduce(sur.solves, op=MPI.SUM), **counts,
            "range": sur.report_range() if sim.rank0 else ""}


def build_summary(sim, end_reason: str, n_steps: int, dt: float, wall: float,
                  force_t: np.ndarray, force_f: np.ndarray, energy) -> dict:
    """The summary of a finished run (collective; the same dict on every rank)."""
    sc, b, cd, comm = sim.scene, sim.ledger, sim.cd, sim.comm
    v0 = sc.projectile.velocity
    v_res = -sim.state.vz
    perforated = bool(end_reason == "perforated" or (end_reason not in ("rebound", "held") and b.n_front == 0
                                                      and sim.state.vz < 0 and b.t_touch is not None))
    W_el = energy.internal - b.viscous - energy.dissipated
    split = time_split(sim)
    steps = max(n_steps, 1)
    chatter = chatter_statistics(force_t, force_f) if sim.rank0 else None
    chatter = comm.bcast(chatter, root=0)
    absorbed = 0.5 * sc.projectile.mass * (v0 ** 2 - v_res ** 2)
    damaged_cells, damage_reach = sim.damage_extent()
    local = sim.material.diagnostics()
    diagnostics = reduce_named(comm, local) if local else {}
    onset = b.damage_onset_position
    return {
        "scene": str(sc.source), "description": sc.description,
        "v0": v0, "residual_velocity": v_res, "perforated": perforated,
        "absorbed_energy": absorbed,
        "max_deflection": b.peak_deflection,
        "damage_onset_time": b.damage_onset_time,
        "damage_onset_deflection": b.damage_onset_deflection,
        "damage_onset_position": list(onset) if onset else None,
        "damage_onset_radius": float(np.hypot(*(np.array(onset) - sim.axis_xy))) if onset else None,
        "damaged_cells": damaged_cells, "damage_extent_radius": damage_reach,
        "first_removal_deflection": b.first_removal_deflection,
        "peak_deflection": b.peak_deflection,
        "energy_error": b.energy_error, "end_reason": end_reason,
        "end_time": cd.time, "wall_time_s": wall, "build_time_s": sim.build_seconds,
        "n_cells": sim.n_cells_global, "n_steps": n_steps, "dt": dt, "dt_initial": sim.dt_initial,
        "dt_changes": [vars(c) for c in sim.dt_changes], "n_ranks": comm.size,
        "deleted_cells": b.deleted, "eroded_cells": b.eroded,
        "removal": _removal_section(sim),
        "free_nodes": comm.allreduce(int(np.count_nonzero(sim.removal.free_nodes)), op=MPI.SUM),
        "energies": {"projectile_kinetic_0": sim.KE0,
                     "projectile_kinetic": 0.5 * sc.projectile.mass * v_res ** 2,
                     "fabric_kinetic": energy.kinetic, "internal_work": energy.internal,
                     "elastic_work": W_el, "stored_energy": W_el - b.damage - b.erosion,
                     "damage_dissipation": b.damage, "erosion_energy": b.erosion,
                     "viscous_dissipation": b.viscous, "terms_dissipation": energy.dissipated,
                     "penalty_energy": b.penalty_energy,
                     "contact_dissipation": -(energy.external + b.W_projectile) - b.penalty_energy,
                     "friction_dissipation_estimate": b.friction_estimate,
                     "membrane_terms": sim.membrane.term_energies()},
        "contact_chatter": chatter, "touch_time": b.t_touch,
        "time_per_step_s": {k: v / steps for k, v in split.items() if k != "surrogate_tiles"},
        "time_total_s": split,
        "surrogate": _surrogate_section(sim, diagnostics),
        "mesh": {"L_min": sim.L_min, "kind": sc.mesh.kind, "element": sc.mesh.element,
                 "quadrature_degree": quadrature_degree(sc)},
        "damping": {"xi": sim.xi, "beta": sim.material.beta, "omega_cell": sim.omega_cell,
                    "omega_max": sim.omega_straight,
                    "xi_mesh": sim.xi_mesh,
                    "share_of_absorbed": b.viscous / absorbed if absorbed > 0 else 0.0},
        "scatter": _scatter_section(sim),
        "largest_yarn_strain": _largest_strain_section(sim),
        "failure": {"rule": sc.material.failure,
                    **({"cracks": sim.failure.summary()} if getattr(sim, "failure", None) is not None else {})},
        "settings": sc.to_dict(),
        **code_fingerprint(),
    }


def _largest_strain_section(sim) -> dict | None:
    """Per yarn family the largest Green strain along it that a live point reached over the run,
    and where (reference centre of its cell, distance from the impact point; collective): with
    damage off, where and how near the yarns come to their strength (the segment's onset), e.g.
    at the projectile's edge or at a clamp. None where the material keeps no such record."""
    peak = getattr(sim.material, "E_peak", None)
    if peak is None:
        return None
    centres, npc = sim._cell_centres(), sim.membrane.n_points_per_cell
    out = {}
    for i, family in enumerate(("warp", "fill")):
        mine = (-math.inf, 0.0, 0.0)
        if peak[i].size:
            k = int(np.argmax(peak[i]))
            mine = (float(peak[i][k]), float(centres[k // npc][0]), float(centres[k // npc][1]))
        value, x, y = max(sim.comm.allgather(mine))
        out[family] = {"green_strain": value, "position": [x, y],
                       "radius": float(np.hypot(x - sim.axis_xy[0], y - sim.axis_xy[1]))}
    return out


def _scatter_section(sim) -> dict:
    """The strength scatter of the run (model, seed, its parameters) and the spread of the cell
    laws it gave, over every rank: the critical stretch per yarn (min, mean, max)."""
    from mpi4py import MPI

    out = dict(sim.scatter.as_dict())
    if sim.laws is None:
        return out
    mu = sim.laws[0][::sim.npc]   # one law per cell
    comm = sim.comm
    count = comm.allreduce(mu.shape[0], op=MPI.SUM)
    for i, yarn in enumerate(("warp", "fill")):
        out[f"mu_crit_{yarn}"] = {
            "min": comm.allreduce(float(mu[:, i].min(initial=float("inf"))), op=MPI.MIN),
            "mean": comm.allreduce(float(mu[:, i].sum()), op=MPI.SUM) / max(count, 1),
            "max": comm.allreduce(float(mu[:, i].max(initial=0.0)), op=MPI.MAX)}
    return out


def _removal_section(sim) -> dict:
    """Where removal happened and why (collective): the removed cells of every rank
    (removed_cells.csv) counted per rule and per yarn families broken in them, their median
    chords (:func:`~fabric_fenicsx.impact.removal_log.removal_statistics`), and the first times
    (s) each yarn family lost strength and broke anywhere."""
    stats = removal_statistics(sim.output.all_removed_cells()) if sim.rank0 else None
    stats = sim.comm.bcast(stats, root=0)
    b = sim.ledger
    return {**stats, "damage_onset_time_s": dict(b.yarn_damage_onset_time),
            "broken_time_s": dict(b.yarn_broken_time), "file": "removed_cells.csv"}
