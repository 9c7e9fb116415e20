"""Ballistic impact of a woven-fabric ply by a rigid flat-ended cylinder (thesis chapter 4).

:class:`ImpactSimulation` is built from a scene (:mod:`.setup`: mesh, fabric, the membrane and
its weak-form terms, the projectile and its contact), a surrogate and a material at the
quadrature points (both built here by default, or passed in), the explicit central difference
and cell removal (:mod:`.removal`). :meth:`ImpactSimulation.run` is the step loop: contact,
fabric step, cell removal, one collective reduction into the energy ledger (:mod:`.ledger`),
the projectile, output (:mod:`.output`), checks for numerical trouble (:mod:`.trouble`), the
time step (:mod:`.timestep`) and the end test; :mod:`.summary` writes what the run computed.
The modelling decisions and the energy balance are in docs/impact_model.md.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.fem.contact_kernel import count_touching, near_nodes
from fabric_fenicsx.fem.explicit import CentralDifference
from fabric_fenicsx.fem.membrane import Membrane
from fabric_fenicsx.fem.mesh import edge_dofs, min_cell_size
from fabric_fenicsx.fem.projectile import ProjectileState, advance
from fabric_fenicsx.fem.yarn_stress import YarnStress, straight_yarn_modulus
from fabric_fenicsx.impact import trouble
from fabric_fenicsx.impact.ledger import EnergyLedger, least, reduce_named
from fabric_fenicsx.impact.pictures import FabricPictures
from fabric_fenicsx.impact.removal import CellRemoval
from fabric_fenicsx.impact.scene import SCATTER_FIELDS, Scene, SceneError
from fabric_fenicsx.impact.setup import (EDGE_TAGS, build_fabric, build_mesh, build_projectile,
                                         build_failure_rule, build_strength_field, build_terms,
                                         quadrature_degree)
from fabric_fenicsx.impact.summary import build_summary
from fabric_fenicsx.impact.timestep import (DtChange, check_due, damping_coefficient, highest_frequency,
                                            unit_cell_frequency)
from fabric_fenicsx.material.contract import QuadratureMaterial

__all__ = ["ImpactError", "ImpactSimulation", "run_impact", "HISTORY_COLUMNS"]

HISTORY_COLUMNS = (
    "time", "projectile_z", "projectile_velocity", "contact_force", "fabric_kinetic",
    "projectile_kinetic", "internal_work", "stored_energy", "damage_dissipation", "erosion_energy",
    "viscous_dissipation", "penalty_energy", "contact_dissipation", "energy_error",
    "central_deflection", "dt", "n_contact", "deleted_cells", "eroded_cells", "membrane_terms_energy",
    "terms_dissipation")
"""history.csv: time (s); projectile face height (m) and velocity (m/s, > 0 into the fabric);
contact force on the projectile (N, > 0 resisting); energies (J; membrane_terms_energy: the
energy stored in the weak-form terms besides the yarns', hourglass control and shear, part of
stored_energy; terms_dissipation: the work of the terms that declare it dissipated);
energy_error (relative);
central deflection (m, > 0 along the impact); dt (s); contact nodes; removed cell counts."""

_BLOW_UP_ENERGY = 1.2   # kinetic energy above this multiple of KE_0 = numerical trouble
_NEGATIVE_WORK = 0.05   # yarns that gave back more than this fraction of KE_0 beyond what they got


class ImpactError(RuntimeError):
    """The impact run stopped on numerical trouble; the message names step, place and fix."""


@dataclass
class _Clock:
    contact: float = 0.0
    output: float = 0.0
    bookkeeping: float = 0.0   # includes dt_check
    dt_check: float = 0.0
    tiles: dict[str, float] = field(default_factory=dict)
    """Seconds of table-tile solves inside each phase (and "step": the fabric's step), to be
    taken out of its time: a one-off cost, not per-step work."""

    def add_tiles(self, phase: str, seconds: float) -> None:
        self.tiles[phase] = self.tiles.get(phase, 0.0) + seconds


@dataclass
class _Loop:
    """What the step loop carries from one step to the next."""
    step: int = 0
    dt: float = 0.0
    dt_prev: float = 0.0      # the last step's dt (the projectile's half step)
    dt_shown: float = 0.0
    fz_prev: float = 0.0
    z_prev: float = 0.0
    next_history: float = 0.0
    next_frame: float = 0.0
    last_progress: float = 0.0
    steps_at_progress: int = 0


class ImpactSimulation:
    """One impact scene on ``comm``: build everything the scene uses, then :meth:`run`.

    out_dir: output folder (created); verbose: progress lines on rank 0; terms: weak-form terms
    (:class:`~fabric_fenicsx.fem.terms.MembraneTerm`) added after those the scene switches on
    or names (``membrane.terms``), before the stable time step is chosen; surrogate: a
    :class:`~fabric_fenicsx.surrogate.table.Surrogate` of the scene's fabric built elsewhere
    (default: built here, tiles from the cache); material: a factory ``material(membrane)``
    returning the :class:`~fabric_fenicsx.material.contract.QuadratureMaterial` at the
    membrane's owned points (default: :class:`~fabric_fenicsx.fem.yarn_stress.YarnStress` over
    the surrogate with the scene's damage switch and damping, :meth:`default_material`).
    """

    def __init__(self, scene: Scene, out_dir: str | os.PathLike, comm: MPI.Comm = MPI.COMM_WORLD,
                 verbose: bool = True, terms=(), surrogate=None,
                 material: Callable[[Membrane], QuadratureMaterial] | None = None):
        from fabric_fenicsx.impact.output import ImpactOutput

        t_build = time.perf_counter()
        self.scene, self.comm, self.verbose = scene, comm, verbose
        self.rank0 = comm.rank == 0
        self.out_dir = Path(out_dir)
        sc = scene

        # -- mesh, fabric, membrane and its weak-form terms
        self.msh, facet_tags = build_mesh(sc, comm)
        self.fabric = build_fabric(sc)
        self.rho_A = self.fabric.areal_density
        self.k_straight = k_straight = straight_yarn_modulus(self.fabric)
        self.membrane = m = Membrane(self.msh, angle=math.radians(sc.material.angle),
                                     quadrature_degree=quadrature_degree(sc))
        for term in (*build_terms(sc, k_straight), *terms):
            m.add_term(term)
        self.n_cells_global = comm.allreduce(m.n_cells, op=MPI.SUM)
        self.npc = m.n_points_per_cell

        # -- damping of the fabric, surrogate and material at the quadrature points
        self.L_min = min_cell_size(self.msh, "area_over_diagonal")
        self.omega_straight = highest_frequency(k_straight, self.rho_A, self.L_min)
        self.xi = sc.run.damping
        self.omega_cell = unit_cell_frequency(self.fabric, k_straight)
        self.beta = damping_coefficient(self.xi, self.omega_cell)
        self.xi_mesh = 0.5 * self.beta * self.omega_straight   # its damping ratio at this mesh's highest frequency
        self.scatter, self.laws, self.damage_range = build_strength_field(sc, self.fabric, m, comm)
        self.failure, self.damage_range = build_failure_rule(sc, self.fabric, m, self.laws, self.damage_range, comm)
        if surrogate is None and material is None:
            surrogate = self.default_surrogate()
        self.surrogate = surrogate
        self.material = (material or self.default_material)(m)
        self._check_material()
        if self.failure is not None:
            if not hasattr(self.material, "failure"):
                raise SceneError(f"material.failure = {sc.material.failure!r} needs a material with a "
                                 f"'failure' hook (YarnStress); {type(self.material).__name__} has none")
            self.material.failure = self.failure
        for term in m.terms:
            if term.follows_integrity:
                term.follow(lambda: self.material.state, self.material.tension)

        # -- integrator, removal of cells
        clamped = edge_dofs(m.V, facet_tags, [EDGE_TAGS[e] for e in sc.boundary.clamped])
        self.cd = CentralDifference(m, self.material, self.rho_A, clamped, damping=0.0,
                                    cell_size=self.L_min, safety=sc.run.dt_safety)
        self.removal = CellRemoval(m, self.material, np.unique(clamped // 3),
                                   sc.material.erosion_strain if sc.material.damage else None)
        self.n_nodes = m.n_owned_nodes
        self.X = m.V.tabulate_dof_coordinates()[:self.n_nodes].copy()
        self.X[:, 2] = 0.0
        self.node_mass = self.cd.mass[0::3].copy()

        # -- projectile and contact
        p = sc.projectile
        self.projectile, self.contact = build_projectile(sc)
        self.state = ProjectileState.initial(self.projectile)
        self.KE0 = self.state.kinetic_energy
        self.axis_xy = np.array([p.x, p.y])
        dist = np.hypot(self.X[:, 0] - p.x, self.X[:, 1] - p.y)
        local = (float(dist.min()), comm.rank) if self.n_nodes else (math.inf, comm.rank)
        _, self.centre_rank = comm.allreduce(local, op=MPI.MINLOC)
        self.centre_node = int(np.argmin(dist)) if comm.rank == self.centre_rank else -1

        # -- time step
        self.dt = self.stable_dt(self._material_modulus())
        self.dt_initial = self.dt
        self.dt_changes: list[DtChange] = []

        with_field = self.laws is not None and "mu_crit1" in self.material.point_fields()
        fields = [f for f in sc.output.fields if f not in SCATTER_FIELDS or with_field]
        self.output = ImpactOutput(self.out_dir, m, fields if sc.output.xdmf_interval > 0 else [],
                                   comm, HISTORY_COLUMNS, scene=sc)
        out = sc.output
        self.pictures = (FabricPictures(m, comm, out.animation_interval if out.animation else 0.0)
                         if out.png or out.animation else None)
        self.ledger = EnergyLedger()
        self.clock = _Clock()
        self._reach = None   # trouble.attached_reach of the scene, taken at the first check
        self._tile_seconds0 = self._tile_seconds()
        self.build_seconds = time.perf_counter() - t_build
        terms = ", ".join(t.name for t in m.terms)
        self._say(f"impact: {sc.source}: {self.n_cells_global} cells on {comm.size} rank(s), "
                  f"L_min = {self.L_min * 1e3:.3f} mm, damping xi = {self.xi:g} at the unit cell (beta = {self.beta:.3e} s, "
                  f"xi = {self.xi_mesh:.3g} at the mesh's highest frequency), "
                  f"dt = {self.dt:.4e} s, v0 = {p.velocity:g} m/s, damage {'on' if sc.material.damage else 'off'}, "
                  f"clamped {sc.boundary.clamped}, angle {sc.material.angle:g} deg, terms: {terms}")

    def default_surrogate(self):
        """The unit cell's surrogate for the scene's fabric, tiles from the scene's cache."""
        from fabric_fenicsx.surrogate.table import Surrogate

        workers = 1 if self.comm.size > 1 else None
        cache = self.scene.material.surrogate_cache or None
        return Surrogate(self.fabric, cache_dir=cache, workers=workers,
                         progress=self.verbose and self.rank0, damage_range=self.damage_range)

    def default_material(self, membrane: Membrane) -> YarnStress:
        """The scene's material: the surrogate at the membrane's points with the scene's damage
        switch and the damping coefficient :attr:`beta`."""
        return YarnStress(self.surrogate, membrane.quadrature_weights_detJ, self.scene.material.damage,
                          self.beta, straight_modulus=self.k_straight, laws=self.laws)

    def _check_material(self) -> None:
        """A material passed in must be a QuadratureMaterial over the membrane's points."""
        mat = self.material
        if not isinstance(mat, QuadratureMaterial):
            missing = [n for n in ("beta", "state", "strains", "update", "max_wave_modulus", "tension",
                                   "point_fields", "energies", "diagnostics", "remove") if not hasattr(mat, n)]
            raise TypeError(f"material {type(mat).__name__} is not a QuadratureMaterial "
                            f"(fabric_fenicsx.material.contract): it lacks {missing}")
        n = self.membrane.n_points
        if mat.state is not None and mat.state.alpha1.shape != (n,):
            raise ValueError(f"material {type(mat).__name__} holds {mat.state.alpha1.shape} points, "
                             f"the membrane has ({n},) owned quadrature points")

    # ------------------------------------------------------------------ small helpers
    @property
    def live_cells(self) -> np.ndarray:
        """Cells of this rank still in the fabric (neither deleted nor eroded)."""
        return self.removal.live_cells

    @property
    def live_nodes(self) -> np.ndarray:
        """Owned nodes touching a live cell on any rank."""
        return self.removal.live_nodes

    def _say(self, text: str) -> None:
        if self.verbose and self.rank0:
            print(text, flush=True)

    def _material_modulus(self) -> float:
        """The material's largest wave modulus over all ranks (N/m)."""
        return self.comm.allreduce(self.material.max_wave_modulus(), op=MPI.MAX)

    def stable_dt(self, material_modulus: float) -> float:
        """The step (s) for the material's largest wave modulus over all ranks: the one rule,
        :meth:`CentralDifference.stable_dt` (the terms' moduli and viscosities, the damping and
        run.dt_safety included). Before the fabric is loaded the modulus is that of the
        reference state (crimped yarns)."""
        modulus = material_modulus + self.membrane.terms_wave_modulus()
        if not (math.isfinite(modulus) and modulus > 0):
            raise ImpactError(f"stable time step: the largest wave modulus is {modulus!r} N/m; the "
                              "surrogate returned no stiffness at the live points (all yarns broken or "
                              "a table problem): check the surrogate with `fabric-fenicsx surrogate`")
        return self.cd.stable_dt(material_modulus=material_modulus)

    # ------------------------------------------------------------------ the step loop
    def run(self) -> dict:
        """Integrate until perforation, rebound, the projectile held (``run.stop_when_held``) or the
        time limit; write the output; return the summary (identical on every rank)."""
        sc, cd = self.scene, self.cd
        t_wall0 = time.perf_counter()
        loop = _Loop(dt=self.dt, dt_shown=self.dt, z_prev=self.state.z, last_progress=t_wall0,
                     next_frame=0.0 if sc.output.xdmf_interval > 0 else math.inf)
        forces = ([], [])          # contact force history (rank 0) for the chatter statistics
        while True:
            t_n = cd.time
            f_ext, f_p, info, uz_c = self._timed("contact", self._contact_and_centre, loop.dt)
            energy = self._fabric_step(loop, t_n, f_ext)
            sums, maxima, check, projectile = self._timed(
                "bookkeeping", self._bookkeeping, loop, t_n, f_p, info, uz_c, energy, forces)
            self._timed("output", self._write, loop, t_n, energy, *projectile)
            self._check_trouble(loop, t_n, energy, projectile[0], maxima)
            loop.step += 1
            loop.dt_prev = loop.dt
            self._next_dt(loop, check, maxima["modulus"])
            self._progress(loop, sums["contact_force"])
            end_reason = self._end_reason(loop, sums["n_attached"])
            if end_reason:
                break
        wall = time.perf_counter() - t_wall0
        return self._finish(end_reason, loop.step, loop.dt, wall, *map(np.array, forces), energy)

    def _timed(self, phase: str, fn, *args):
        """``fn(*args)``, its wall time and the table tiles solved in it added to the clock's ``phase``."""
        t0, tiles = time.perf_counter(), self._tile_seconds()
        result = fn(*args)
        setattr(self.clock, phase, getattr(self.clock, phase) + time.perf_counter() - t0)
        self.clock.add_tiles(phase, self._tile_seconds() - tiles)
        return result

    def _tile_seconds(self) -> float:
        """Seconds the surrogate has spent solving table tiles so far (0 without one)."""
        return self.surrogate.build_seconds if self.surrogate is not None else 0.0

    def _contact_and_centre(self, dt: float):
        """:meth:`_contact` and the central node's displacement along z at t_n (this rank's)."""
        f_ext, f_p, info = self._contact(dt)
        uz_c = float(self.cd.u[3 * self.centre_node + 2]) if self.centre_node >= 0 else 0.0
        return f_ext, f_p, info, uz_c

    def _bookkeeping(self, loop: _Loop, t_n: float, f_p, info, uz_c: float, energy, forces):
        """After the fabric's step: cell removal, the collective reduction, the ledger, the
        projectile to t_n + dt. Returns (sums, maxima, whether dt was checked, (KE_p, v_full,
        W_contact) of the projectile at t_n)."""
        removed = self.removal.select()
        if removed[0].size or removed[1].size:
            self.removal.remove(*removed, time=t_n)
        check = check_due(loop.step, self.ledger.step_touch, self.scene.run.dt_check_interval)
        sums, maxima = self._reduce(loop, t_n, f_p, info, uz_c, removed, check)
        self._book(loop, t_n, sums, maxima)
        projectile = self._projectile(loop, sums["contact_force"], energy)
        if self.rank0:
            forces[0].append(t_n)
            forces[1].append(sums["contact_force"])
        return sums, maxima, check, projectile

    # ------------------------------------------------------------------ one step's parts
    def _contact(self, dt: float):
        """Contact forces at t_n on this rank's live owned nodes near the projectile."""
        s, proj = self.state, self.projectile
        n_dofs = self.membrane.n_owned_dofs
        margin = abs(s.vz) * dt + 1e-9
        if not proj.may_touch(self.ledger.z_max, s.z, margin):
            return None, np.zeros(3), _no_contact()
        sel, x_sel = near_nodes(self.X, self.cd.u, self.removal.live_nodes, self.axis_xy[0],
                                self.axis_xy[1], proj.radius, s.z, proj.length)
        if sel.size == 0:
            return None, np.zeros(3), _no_contact()
        v = self.cd.v.reshape(-1, 3)
        f_nodes, f_p, info = self.contact.forces(x_sel, v[sel], self.node_mass[sel], dt, s)
        # touching nodes of fabric still attached to a clamped edge (a plug riding on the
        # face does not keep the run from ending)
        info["n_attached"] = int(count_touching(f_nodes, sel, self.removal.free_nodes))
        f_ext = np.zeros(n_dofs)
        f_ext.reshape(-1, 3)[sel] = f_nodes
        return f_ext, f_p, info

    def _fabric_step(self, loop: _Loop, t_n: float, f_ext):
        """The membrane from t_n to t_n + dt; numerical trouble becomes an :class:`ImpactError`."""
        tiles = self._tile_seconds()
        if self.failure is not None:
            self.failure.time = t_n
        try:
            return self.cd.step(loop.dt, f_ext)
        except trouble.STEP_ERRORS as err:
            raise ImpactError(self._trouble(loop.step, t_n, f"{type(err).__name__}: {err}",
                                            trouble.component(err))) from err
        finally:
            self.clock.add_tiles("step", self._tile_seconds() - tiles)

    def _reduce(self, loop: _Loop, t_n: float, f_p, info, uz_c: float, removed: tuple, check: bool):
        """This step's values summed and maximised over all ranks (two collective calls)."""
        mat, cd, removal = self.material, self.cd, self.removal
        delete, erode = removed
        state = mat.state
        # how far each yarn family has gone anywhere: 1 - min alpha_i (which breaks first)
        yarn_damage = ({"warp_damage": 1.0 - float(least(state.alpha1, 1.0)),
                        "fill_damage": 1.0 - float(least(state.alpha2, 1.0))}
                       if self.scene.material.damage else {"warp_damage": 0.0, "fill_damage": 0.0})
        damaged = yarn_damage["warp_damage"] > 0.0 or yarn_damage["fill_damage"] > 0.0
        z_max, front, moved = removal.node_extremes(self.X, cd.u, self.axis_xy, self.projectile.radius,
                                                    self.state.z + self.projectile.length)
        sums = reduce_named(self.comm, {
            "contact_force": f_p[2], "penalty_energy": info["penalty_energy"],
            "friction_dissipation": -info["friction_work"], "n_contact": info["n_active"],
            **mat.energies(), "deleted": delete.size, "eroded": erode.size,
            "damaged": float(damaged), "central_uz": uz_c, "n_front": front,
            "n_attached": info["n_attached"]})
        tw, tiles = time.perf_counter(), self._tile_seconds()
        try:
            modulus = mat.max_wave_modulus(self.scene.run.dt_check_interval) if check else 0.0
        except trouble.STEP_ERRORS as err:
            raise ImpactError(self._trouble(loop.step, t_n, f"time-step check: {type(err).__name__}: "
                                            f"{err}", trouble.component(err))) from err
        self.clock.dt_check += time.perf_counter() - tw
        self.clock.add_tiles("dt_check", self._tile_seconds() - tiles)
        maxima = reduce_named(self.comm, {"z_max": z_max, "modulus": modulus,
                                          "attached_displacement": moved, **yarn_damage}, op=MPI.MAX)
        return sums, maxima

    def _book(self, loop: _Loop, t_n: float, sums: dict, maxima: dict) -> None:
        """The step's reduced values into the ledger; removed cells update the node sets."""
        ledger = self.ledger
        if sums["deleted"] or sums["eroded"]:
            self.removal.update_nodes()
            self.output.removed_cells(self.removal.new_records())
        if self.failure is not None:
            cracked = self.failure.new_cracks()
            if cracked.size:
                self.output.cracks(cracked)
        ledger.book_step(sums, maxima)
        ledger.book_yarn_damage(t_n, maxima["warp_damage"], maxima["fill_damage"])
        if -sums["central_uz"] >= ledger.peak_deflection:
            self._picture("largest deflection", t_n, -sums["central_uz"])
        if sums["n_contact"] > 0 and ledger.t_touch is None:
            ledger.t_touch, ledger.step_touch = t_n, loop.step
        if sums["n_attached"] > 0:
            ledger.t_last_contact = t_n
        if sums["damaged"] and ledger.damage_onset_time is None:
            ledger.damage_onset_time = t_n
            ledger.damage_onset_deflection = -sums["central_uz"]
            ledger.damage_onset_position = self._onset_position()
            self._picture("damage onset", t_n, -sums["central_uz"])
            x, y = ledger.damage_onset_position
            self._say(f"  damage starts at t = {t_n * 1e6:.2f} us, central deflection "
                      f"{-sums['central_uz'] * 1e3:.2f} mm, in the cell at (x, y) = ({x * 1e3:.1f}, "
                      f"{y * 1e3:.1f}) mm")

    def _picture(self, name: str, t: float, deflection: float) -> None:
        """Keep the fabric's state for snapshots.png (no-op without pictures)."""
        if self.pictures is not None:
            self.pictures.keep(name, t, deflection, self.material.state.alpha1, self.live_cells)

    def _onset_position(self) -> tuple[float, float]:
        """Reference (x, y) of the centre of the cell whose point is the most damaged at damage
        onset (smallest min(alpha1, alpha2) over all ranks; collective): where the first yarn
        starts to break, under the projectile or remote from it."""
        state = self.material.state
        alpha = np.minimum(state.alpha1, state.alpha2)
        mine = (math.inf, 0.0, 0.0)
        if alpha.size and alpha.min() < 1.0:
            centre = self._cell_centres()[int(np.argmin(alpha)) // self.membrane.n_points_per_cell]
            mine = (float(alpha.min()), float(centre[0]), float(centre[1]))
        _, x, y = min(self.comm.allgather(mine))
        return x, y

    def _cell_centres(self) -> np.ndarray:
        """Reference (x, y) of the centre of every owned cell, shape (n_cells, 2)."""
        if getattr(self, "_centres", None) is None:
            m = self.membrane
            nodes = m.V.dofmap.list.array.reshape(-1, m.V.dofmap.dof_layout.num_dofs)[:m.n_cells]
            self._centres = m.V.tabulate_dof_coordinates()[nodes, :2].mean(axis=1)
        return self._centres

    def damage_extent(self) -> tuple[int, float | None]:
        """Cells with a damaged point (removed ones included) over all ranks, and the largest
        distance of such a cell's centre from the impact point (m; None without damage): how
        far the damage spread (thesis Sec. 4.4: local against remote damage)."""
        m, state = self.membrane, self.material.state
        damaged = (np.minimum(state.alpha1, state.alpha2) < 1.0).reshape(m.n_cells, -1).any(axis=1)
        r = np.hypot(*(self._cell_centres()[damaged] - self.axis_xy).T)
        n = self.comm.allreduce(int(damaged.sum()), op=MPI.SUM)
        reach = self.comm.allreduce(float(r.max()) if r.size else -1.0, op=MPI.MAX)
        return n, (reach if n else None)

    def _projectile(self, loop: _Loop, fz: float, energy) -> tuple[float, float, float]:
        """Energy balance at t_n and the projectile to t_n + dt: (KE_p, v_full, W_contact)."""
        s, ledger = self.state, self.ledger
        vz_full = s.vz + 0.5 * loop.dt_prev * fz / s.mass
        ledger.W_projectile += 0.5 * (loop.fz_prev + fz) * (s.z - loop.z_prev)
        KE_p = 0.5 * s.mass * vz_full ** 2
        W_contact = energy.external + ledger.W_projectile
        total = energy.kinetic + KE_p + energy.internal - W_contact - energy.support
        ledger.error_now = abs(total - self.KE0) / self.KE0
        ledger.energy_error = max(ledger.energy_error, ledger.error_now)
        loop.z_prev, loop.fz_prev = s.z, fz
        self.state = advance(s, fz, loop.dt)
        return KE_p, vz_full, W_contact

    def _write(self, loop: _Loop, t_n: float, energy, KE_p, vz_full, W_contact) -> None:
        """history.csv and XDMF frames at their intervals."""
        out = self.scene.output
        if t_n >= loop.next_history:
            self.output.history(self._history_row(t_n, energy, KE_p, vz_full, W_contact, loop.dt))
            loop.next_history = _next_time(loop.next_history, out.history_interval, t_n)
        if t_n >= loop.next_frame:
            self._frame(t_n)
            loop.next_frame = _next_time(loop.next_frame, out.xdmf_interval, t_n)
        if self.pictures is not None and self.pictures.frame_due(t_n):
            self.pictures.add_frame(t_n, -self.ledger.central_uz, self.material.state.alpha1, self.live_cells)

    def _check_trouble(self, loop: _Loop, t_n: float, energy, KE_p: float, maxima: dict) -> None:
        """Stop with a clear message on a blow-up or a broken energy balance."""
        ledger, sc = self.ledger, self.scene
        kinetic = energy.kinetic + KE_p
        W_el = energy.internal - ledger.viscous - energy.dissipated
        moved = maxima["attached_displacement"]
        if self._reach is None:
            self._reach = trouble.attached_reach(sc.mesh.side, self.removal.erosion_strain)
        reach = self._reach
        if (kinetic > _BLOW_UP_ENERGY * self.KE0 or W_el < -_NEGATIVE_WORK * self.KE0 or moved > reach
                or ledger.error_now > sc.run.energy_tolerance):
            self._stop_on_trouble(loop, t_n, kinetic, W_el, moved, reach)

    def _stop_on_trouble(self, loop: _Loop, t_n: float, kinetic: float, W_el: float, moved: float,
                         reach: float) -> None:
        """The :class:`ImpactError` of :meth:`_check_trouble` once one of its tests tripped."""
        ledger, sc = self.ledger, self.scene
        tripped = [what for bad, what in (
            (kinetic > _BLOW_UP_ENERGY * self.KE0,
             f"kinetic energy {kinetic:.4g} J > {_BLOW_UP_ENERGY:g} x the impact energy KE_0 = "
             f"{self.KE0:.4g} J"),
            (W_el < -_NEGATIVE_WORK * self.KE0,
             f"the yarns gave back {-W_el:.4g} J more than they received (> {_NEGATIVE_WORK:g} KE_0)"),
            (moved > reach,
             f"fabric attached to a clamped edge moved {moved:.4g} m, farther than it can reach "
             f"({reach:.4g} m: {'the fabric side' if self.removal.erosion_strain is None else 'two fabric sides at the erosion strain, and back'})")) if bad]
        if tripped:
            attached = self.removal.live_nodes & ~self.removal.free_nodes
            raise ImpactError(self._trouble(loop.step, t_n, "blow-up: " + "; ".join(tripped),
                                            among=attached if moved > reach else None))
        if ledger.error_now > sc.run.energy_tolerance:
            raise ImpactError(self._trouble(
                loop.step, t_n, f"energy balance error {ledger.error_now:.3%} > run.energy_tolerance = "
                f"{sc.run.energy_tolerance:g} (damage {'on' if sc.material.damage else 'off'}; the balance "
                f"KE + W_internal - W_contact = KE_0 no longer holds: the step is too large for "
                f"the contact or the fabric's stiffness)"))

    def _next_dt(self, loop: _Loop, check: bool, modulus: float) -> None:
        """Lower dt when the re-checked wave modulus asks for it; every change is in the
        summary, on screen those of 1 % or more since the last shown."""
        if not (check and modulus > 0):
            return
        dt_new = self.stable_dt(modulus)
        if dt_new < loop.dt:
            self.dt_changes.append(DtChange(loop.step, self.cd.time, loop.dt, dt_new, float(modulus)))
            if dt_new < 0.99 * loop.dt_shown:
                self._say(f"  dt {loop.dt_shown:.4e} -> {dt_new:.4e} s at step {loop.step} (t = "
                          f"{self.cd.time * 1e6:.2f} us, wave modulus {modulus:.4g} N/m)")
                loop.dt_shown = dt_new
            loop.dt = dt_new

    def _progress(self, loop: _Loop, fz: float) -> None:
        now = time.perf_counter()
        if (self.verbose and self.scene.output.progress_interval > 0
                and now - loop.last_progress >= self.scene.output.progress_interval):
            b = self.ledger
            rate = (loop.step - loop.steps_at_progress) / (now - loop.last_progress)
            self._say(f"  t = {self.cd.time * 1e6:8.2f} us  step {loop.step:7d}  {rate:7.1f} steps/s  "
                      f"v = {-self.state.vz:8.3f} m/s  F = {fz:9.1f} N  dt = {loop.dt:.3e} s  "
                      f"removed {b.deleted}+{b.eroded}  energy error {b.error_now:.2e}")
            loop.last_progress, loop.steps_at_progress = now, loop.step

    def _end_reason(self, loop: _Loop, n_attached: float) -> str | None:
        run, ledger, t = self.scene.run, self.ledger, self.cd.time
        released = (ledger.t_last_contact is not None and n_attached == 0
                    and t - ledger.t_last_contact >= run.release_time)
        if released and self.state.vz > 0:
            return "rebound"
        if released and ledger.n_front == 0:
            return "perforated"
        if run.stop_when_held and ledger.t_touch is not None and self.state.vz > 0:
            return "held"
        if t >= run.t_end:
            return "time_limit"
        if run.max_steps and loop.step >= run.max_steps:
            return "max_steps"
        return None

    # ------------------------------------------------------------------ output pieces
    def _history_row(self, t, energy, KE_p, vz_full, W_contact, dt) -> dict:
        b = self.ledger
        W_el = energy.internal - b.viscous - energy.dissipated
        return {"time": t, "projectile_z": self.state.z, "projectile_velocity": -vz_full,
                "contact_force": b.contact_force, "fabric_kinetic": energy.kinetic,
                "projectile_kinetic": KE_p, "internal_work": energy.internal,
                "stored_energy": W_el - b.damage - b.erosion, "damage_dissipation": b.damage,
                "erosion_energy": b.erosion, "viscous_dissipation": b.viscous,
                "penalty_energy": b.penalty_energy,
                "contact_dissipation": -W_contact - b.penalty_energy, "energy_error": b.error_now,
                "central_deflection": -b.central_uz, "dt": dt, "n_contact": b.n_contact,
                "deleted_cells": b.deleted, "eroded_cells": b.eroded,
                "membrane_terms_energy": sum(self.membrane.term_energies().values()),
                "terms_dissipation": energy.dissipated}

    def point_fields(self) -> dict[str, np.ndarray]:
        """Point values (owned quadrature points) of the cell-wise output fields: the
        material's (:meth:`~fabric_fenicsx.material.contract.QuadratureMaterial.point_fields`)."""
        return self.material.point_fields()

    def _frame(self, t: float) -> None:
        """One XDMF frame of the state at t_n, the start of the last step: the time at which the
        point fields (stresses, strains, damage) were evaluated and history.csv took its row.
        In the step loop t is t_n; at the end of a run (t = t_n + dt) the frame is the last
        step's t_n, not repeated if already written. The step has already moved u to u_{n+1}
        and v to v_{n+1/2}: u_n = u_{n+1} - du, v_n = v_{n+1/2} - dt/2 a_n."""
        t_n, u, v = self.cd.evaluated_state()
        self.output.frame(t_n, u, v, self.point_fields(), self.live_cells)

    def _trouble(self, step: int, t: float, what: str, component: str = "membrane", among=None) -> str:
        """A message naming step, time, the component that failed (membrane, unit cell, table
        tile), place (the node that moved most, among the owned nodes of the mask ``among`` if
        given: the attached fabric), the step the run used and what can help (:mod:`.trouble`)."""
        cache = self.surrogate.cache_dir if self.surrogate is not None else "the surrogate cache"
        where = trouble.place(self.cd.u.reshape(-1, 3)[:self.n_nodes], self.X, self.comm.rank, among,
                              "the attached fabric" if among is not None else "")
        return (f"impact run stopped at step {step}, t = {t:.6e} s: in the {component}: {what}; "
                f"{where}; "
                f"dt = {self.cd._dt_prev:.3e} s, projectile at z = {self.state.z:.4e} m moving "
                f"{-self.state.vz:.3f} m/s. {trouble.fixes(component, cache)}; see "
                f"{self.out_dir / 'history.csv'}")

    def _finish(self, end_reason, n_steps, dt, wall, force_t, force_f, energy) -> dict:
        """The last frame, summary.json, pictures and the closing line."""
        cd, b = self.cd, self.ledger
        self._frame(cd.time)
        summary = build_summary(self, end_reason, n_steps, dt, wall, force_t, force_f, energy)
        beyond = summary["surrogate"]["points_beyond_table_damage_off"]
        if beyond and self.surrogate is not None:
            st = self.surrogate.stats
            self._say(f"impact: WARNING: with damage off, {beyond} point evaluations had a yarn "
                      f"strain above the surrogate's table (E > {self.surrogate.E_table[1]:.4g}; largest "
                      f"E1 = {st.E_max[0]:.4g}, E2 = {st.E_max[1]:.4g} on rank 0): their stress was "
                      "taken at the table's end, so the run left the model's range there")
        self.output.finish(summary, self.live_cells, self.point_fields(), self.scene.output.png)
        if self.pictures is not None:
            self._picture("end", cd.time, -b.central_uz)
            self.pictures.write(self.out_dir, snapshots=self.scene.output.png)
        v0, v_res = summary["v0"], summary["residual_velocity"]
        self._say(f"impact: {end_reason} at t = {cd.time * 1e6:.1f} us after {n_steps} steps "
                  f"({wall:.1f} s): v0 = {v0:g} m/s, residual velocity {v_res:.3f} m/s, absorbed "
                  f"{summary['absorbed_energy']:.2f} J, energy error {b.energy_error:.2e}, removed cells "
                  f"{b.deleted} deleted + {b.eroded} eroded")
        if b.deleted + b.eroded:
            self._say(_removal_line(summary["removal"]))
        if self.rank0 and self.output.xdmf_path is not None and self.verbose:
            print(f"impact: XDMF for ParaView: {self.output.xdmf_path.resolve()} (one grid per frame "
                  f"with every field; `pvpython {self.output.xdmf_path.with_name('paraview_view.py').resolve()}` "
                  "warps it, hides the removed cells and colours by SDV2)", flush=True)
        return summary


def run_impact(scene: Scene, out_dir: str | os.PathLike, comm: MPI.Comm = MPI.COMM_WORLD,
               verbose: bool = True, terms=(), surrogate=None, material=None) -> dict:
    """Build and run one impact scene; returns the summary (also in out_dir/summary.json).
    ``terms``, ``surrogate``, ``material``: as for :class:`ImpactSimulation`."""
    sim = ImpactSimulation(scene, out_dir, comm, verbose, terms=terms, surrogate=surrogate,
                           material=material)
    try:
        return sim.run()
    finally:
        sim.output.close()


def _removal_line(removal: dict) -> str:
    """The closing line on where removal happened: cells by the yarn families broken in them,
    when each family first lost strength and broke, the median chords of the removed cells."""
    states, first, broken = removal["by_family_state"], removal["damage_onset_time_s"], removal["broken_time_s"]
    chord = removal["median_chord_m"]

    def us(t):
        return "never" if t is None else f"{t * 1e6:.1f} us"

    return (f"impact: removed cells with yarns broken (alpha < {removal['broken_below_alpha']:g}): "
            f"warp only {states['warp_only']}, fill only {states['fill_only']}, both {states['both']}, "
            f"neither {states['neither']}; first damage warp {us(first['warp'])}, fill {us(first['fill'])}; "
            f"first alpha = 0 warp {us(broken['warp'])}, fill {us(broken['fill'])}; median chord "
            f"warp {chord['warp'] * 1e3:.2f} mm, fill {chord['fill'] * 1e3:.2f} mm (removed_cells.csv)")


def _no_contact() -> dict:
    """The contact ``info`` of a step without contact on this rank."""
    return dict(penalty_energy=0.0, friction_work=0.0, damping_work=0.0, n_active=0, n_attached=0,
                max_penetration=0.0, normal_force=0.0)


def _next_time(t_next: float, interval: float, t_n: float) -> float:
    """The next output time after ``t_next`` on the grid of ``interval``, past t_n."""
    t_next += interval
    while t_next <= t_n:
        t_next += interval
    return t_next
