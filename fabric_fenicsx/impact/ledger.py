"""The energy ledger of an impact run: global energies and run state, the same on every rank.

Each step the ranks' contributions are summed (or maximised) in one collective call by
:func:`reduce_named`, which keeps their names: ``sums["viscous_dissipation"]``, not ``glob[4]``.
The balance KE_fabric + KE_projectile + W_internal - W_contact = KE_0 is explained in
docs/impact_model.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from numba import njit

__all__ = ["EnergyLedger", "reduce_named", "least"]


@njit(cache=True, nogil=True)
def least(a, initial):
    """a.min(initial=initial) of a 1-D array (NaN if one is), compiled: the step's smallest
    integrities without numpy's dispatch. Of two equal values either may be the result (numpy's
    order of reduction decides which zero it gives)."""
    smallest = initial
    for value in a:
        if value != value:
            return value
        if value < smallest:
            smallest = value
    return smallest


def reduce_named(comm, values: dict[str, float], op=MPI.SUM) -> dict[str, float]:
    """The named values reduced over all ranks with ``op`` (one Allreduce, in the dict's order;
    on one rank the values themselves, as floats)."""
    local = np.array(list(values.values()), dtype=float)
    if comm.size == 1:
        return dict(zip(values, local))
    total = np.empty_like(local)
    comm.Allreduce(local, total, op=op)
    return dict(zip(values, total))


@dataclass
class EnergyLedger:
    """Global energies (J) and run state, identical on every rank."""
    W_projectile: float = 0.0       # work of the contact force on the projectile
    penalty_energy: float = 0.0
    friction_estimate: float = 0.0  # -sum friction_work (first-order split, PenaltyContact)
    viscous: float = 0.0
    damage: float = 0.0
    erosion: float = 0.0
    energy_error: float = 0.0
    error_now: float = 0.0
    deleted: int = 0
    eroded: int = 0
    n_contact: int = 0
    contact_force: float = 0.0
    central_uz: float = 0.0
    z_max: float = 0.0
    n_front: int = 0
    t_touch: float | None = None
    step_touch: int | None = None
    t_last_contact: float | None = None
    damage_onset_time: float | None = None
    damage_onset_deflection: float | None = None
    damage_onset_position: tuple[float, float] | None = None   # reference (x, y) of the first damaged cell
    first_removal_deflection: float | None = None   # central deflection when a cell first goes
    peak_deflection: float = 0.0                     # largest central deflection of the run
    yarn_damage_onset_time: dict = field(default_factory=lambda: {"warp": None, "fill": None})
    """t_n of the first step with a point of the yarn family below alpha = 1, over all ranks (s)."""
    yarn_broken_time: dict = field(default_factory=lambda: {"warp": None, "fill": None})
    """t_n of the first step with a point of the yarn family at alpha = 0 (s)."""

    def book_step(self, sums: dict[str, float], maxima: dict[str, float]) -> None:
        """Take one step's reduced values (see ``ImpactSimulation._reduce``)."""
        self.deleted += int(sums["deleted"])
        self.eroded += int(sums["eroded"])
        self.penalty_energy = sums["penalty_energy"]
        self.viscous = sums["viscous_dissipation"]
        self.damage = sums["damage_dissipation"]
        self.erosion = sums["erosion_energy"]
        self.friction_estimate += sums["friction_dissipation"]
        self.n_contact = int(sums["n_contact"])
        self.contact_force = sums["contact_force"]
        self.central_uz = sums["central_uz"]
        self.peak_deflection = max(self.peak_deflection, -self.central_uz)
        if (sums["deleted"] or sums["eroded"]) and self.first_removal_deflection is None:
            self.first_removal_deflection = -self.central_uz
        self.z_max = maxima["z_max"]
        self.n_front = int(sums["n_front"])

    def book_yarn_damage(self, t: float, warp_damage: float, fill_damage: float) -> None:
        """The first times (t_n, s) each yarn family lost strength (1 - min alpha_i > 0) and
        broke (min alpha_i = 0) anywhere."""
        for yarn, d in (("warp", warp_damage), ("fill", fill_damage)):
            if d > 0.0 and self.yarn_damage_onset_time[yarn] is None:
                self.yarn_damage_onset_time[yarn] = t
            if d >= 1.0 and self.yarn_broken_time[yarn] is None:
                self.yarn_broken_time[yarn] = t
