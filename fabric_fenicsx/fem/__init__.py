"""Finite-element layer (DOLFINx 0.5.2): meshes, the membrane and its weak-form terms, the
quadrature-point adapter of the surrogate, the explicit integrator, contact and the rigid
projectile.

- :mod:`.mesh`: gmsh fabric meshes and uniform squares, clamped edges, cell sizes;
- :mod:`.membrane`: kinematics F = I_32 + Grad u, yarn strains, live-cell mask, assembly;
- :mod:`.terms`: weak-form terms (yarn stresses, isotropic shear, your own);
- :mod:`.yarn_stress`: the surrogate at the quadrature points (``YarnStress``);
- :mod:`.explicit`: central difference with a lumped mass and energy bookkeeping;
- :mod:`.timestep`: the one stable-time-step rule (damped Courant limit);
- :mod:`.projectile`: rigid projectile and penalty contact with friction.

Names are re-exported lazily: ``import fabric_fenicsx.fem`` alone does not load DOLFINx.
"""
from fabric_fenicsx._lazy import lazy_exports

_EXPORTS = {
    "MeshSpec": "mesh", "load_mesh": "mesh", "uniform_square": "mesh", "edge_dofs": "mesh",
    "min_cell_size": "mesh", "Membrane": "membrane", "yarn_directions": "membrane",
    "MembraneTerm": "terms", "FollowsIntegrity": "terms", "YarnTerm": "terms", "IsotropicShear": "terms",
    "HourglassControl": "terms", "stable_dt": "timestep",
    "YarnStress": "yarn_stress", "straight_yarn_modulus": "yarn_stress",
    "CentralDifference": "explicit", "EnergyRecord": "explicit", "LinearYarnMaterial": "explicit",
    "Projectile": "projectile", "ProjectileState": "projectile", "PenaltyContact": "projectile",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
