"""From a scene to the model's parts: fabric, strength field, mesh, weak-form terms, projectile and contact."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.fem.mesh import BOTTOM, LEFT, RIGHT, TOP, MeshSpec, aligned_square, load_mesh, uniform_square
from fabric_fenicsx.fem.mesh_file import read_square_msh
from fabric_fenicsx.fem.projectile import PenaltyContact, Projectile
from fabric_fenicsx.fem.terms import HourglassControl, IsotropicShear, MembraneTerm
from fabric_fenicsx.fem.crack_rules import CRACK_RULES, crack_rule_on_cells
from fabric_fenicsx.impact.output import cell_corners
from fabric_fenicsx.impact.scene import Scene, SceneError, load_fabric
from fabric_fenicsx.impact.term_specs import build_scene_terms
from fabric_fenicsx.material.fabric import Fabric, zylon_as
from fabric_fenicsx.material.scatter import DamageRange, StrengthScatter, cell_laws

__all__ = ["EDGE_TAGS", "build_fabric", "build_mesh", "build_terms", "build_projectile", "quadrature_degree",
           "build_strength_field", "FAILURE_RULES", "build_failure_rule"]

EDGE_TAGS = {"left": LEFT, "right": RIGHT, "bottom": BOTTOM, "top": TOP}
"""Scene edge names -> facet tags of the fabric meshes."""


def build_fabric(scene: Scene) -> Fabric:
    """The scene's fabric: a TOML file (``fabric.file``; a bad one raises
    :class:`~fabric_fenicsx.impact.scene.SceneError` naming it) or a built-in (Table 1)."""
    if scene.fabric.file:
        return load_fabric(scene)
    return zylon_as(bending=scene.fabric.bending)


def build_mesh(scene: Scene, comm):
    """(mesh, facet tags) of the scene: n x n squares, the graded gmsh mesh fine at the
    impact point, the graded grid along x and y with the same sizes (``aligned``), a structured
    patch turned ``mesh.rotation`` degrees in the graded gmsh mesh (``structured``), or a
    user's file (``file``; a bad one raises :class:`~fabric_fenicsx.impact.scene.SceneError`)."""
    ms = scene.mesh
    if ms.kind == "uniform":
        msh, _, facet_tags = uniform_square(ms.n, ms.side, comm)
        return msh, facet_tags
    if ms.kind == "file":
        try:
            msh, _, facet_tags = read_square_msh(ms.file, ms.side, comm)
        except ValueError as err:
            raise SceneError(f"mesh.file: {err}") from None
        return msh, facet_tags
    try:
        spec = MeshSpec(side=ms.side, h_centre=ms.h_centre, h_edge=ms.h_edge,
                        refine_radius=ms.refine_radius, centre=(scene.projectile.x, scene.projectile.y),
                        grading=ms.grading, rotation=ms.rotation if ms.kind == "structured" else None)
    except ValueError as err:
        raise SceneError(str(err).replace("MeshSpec.", "mesh.")) from None
    if ms.kind == "aligned":
        msh, _, facet_tags = aligned_square(spec, comm)
    else:
        msh, _, facet_tags = load_mesh(spec, comm)
    return msh, facet_tags


def quadrature_degree(scene: Scene) -> int:
    """Quadrature degree of the yarn stresses: ``mesh.quadrature_degree`` for the full element,
    1 (one point per cell) for the reduced one."""
    return 1 if scene.mesh.element == "reduced" else scene.mesh.quadrature_degree


def build_terms(scene: Scene, straight_modulus: float) -> list[MembraneTerm]:
    """The weak-form terms the scene switches on besides the yarns' (``[membrane]``): the
    hourglass control of the reduced element (stiffness ``membrane.hourglass`` x
    ``straight_modulus``, N/m), an isotropic shear stiffness and the terms the scene names
    (``membrane.terms``, :mod:`fabric_fenicsx.impact.term_specs`), in that order."""
    terms: list[MembraneTerm] = []
    if scene.mesh.element == "reduced":
        terms.append(HourglassControl(scene.membrane.hourglass, straight_modulus))
    if scene.membrane.shear_modulus > 0:
        terms.append(IsotropicShear(scene.membrane.shear_modulus))
    terms.extend(build_scene_terms(scene.membrane.terms))
    return terms


def build_projectile(scene: Scene) -> tuple[Projectile, PenaltyContact]:
    """The rigid projectile of the scene and its penalty contact with the fabric."""
    p = scene.projectile
    projectile = Projectile(diameter=p.diameter, length=p.length, fillet=p.fillet, mass=p.mass,
                            velocity=p.velocity, friction=p.friction, axis_xy=(p.x, p.y), z0=p.standoff)
    contact = PenaltyContact(projectile, damping_ratio=p.contact_damping,
                             penalty_fraction=p.penalty_fraction)
    return projectile, contact


def build_strength_field(scene: Scene, fabric: Fabric, membrane, comm):
    """The scene's strength scatter (``material.scatter``, :mod:`fabric_fenicsx.material.scatter`)
    at the membrane's owned points: (scatter, laws, damage range). ``laws`` is None with scatter
    "none", else (mu_crit, scale), each (n_points, 2): the law of each point's cell
    (:func:`~fabric_fenicsx.material.scatter.cell_laws` over its reference corners). The damage
    range is the bounds over every rank's points, so every rank builds the same table."""
    mat = scene.material
    scatter = StrengthScatter(mat.scatter, mat.seed, mat.weibull_modulus, mat.fibrils)
    if not scatter.on:
        return scatter, None, None
    X = membrane.V.tabulate_dof_coordinates()[:, :2]
    corners = X[cell_corners(membrane.V, membrane.n_cells)]
    mu_crit, scale = cell_laws(scatter, fabric, mat.angle, corners)
    npc = membrane.n_points_per_cell
    mu_crit, scale = np.repeat(mu_crit, npc, axis=0), np.repeat(scale, npc, axis=0)
    local = scatter.damage_range(fabric, mu_crit, scale)
    lo = [comm.allreduce(float(x), op=MPI.MIN) for x in local.mu_crit_min]
    hi = [comm.allreduce(float(x), op=MPI.MAX) for x in local.mu_complete_max]
    return scatter, (mu_crit, scale), type(local)(np.array(lo), np.array(hi))


def _yarn_crack(scene: Scene, fabric: Fabric, membrane, laws, comm):
    """The crack-tracking rule ``material.failure`` names
    (:data:`~fabric_fenicsx.fem.crack_rules.CRACK_RULES`) on the membrane's cells,
    over the points' segment laws ``laws`` (None: the fabric's)."""
    from fabric_fenicsx.fem.membrane import yarn_directions

    rule = scene.material.failure
    if comm.size > 1:
        raise SceneError(f"material.failure = {rule!r} runs on one rank (its cracks are not exchanged "
                         "between ranks): run without mpirun, or with material.failure = 'thesis'")
    if not scene.material.damage:
        return None
    X = membrane.V.tabulate_dof_coordinates()[:, :2]
    corners = X[cell_corners(membrane.V, membrane.n_cells)]
    return crack_rule_on_cells(rule, corners, yarn_directions(membrane.angle), fabric,
                               membrane.n_points_per_cell, laws, comm)


FAILURE_RULES = {"thesis": None, **{name: _yarn_crack for name in CRACK_RULES}}
"""``material.failure`` -> a builder (scene, fabric, membrane, laws, comm) -> the rule that the
material's ``failure`` takes (None: each point's own law, the thesis's rule)."""


def build_failure_rule(scene: Scene, fabric: Fabric, membrane, laws, damage_range, comm):
    """(rule, damage range): the scene's failure rule (``material.failure``, :data:`FAILURE_RULES`)
    and the damage range the surrogate's table must hold for it and the strength field
    (``damage_range``, None: the fabric's own law)."""
    builder = FAILURE_RULES[scene.material.failure]
    rule = builder(scene, fabric, membrane, laws, comm) if builder is not None else None
    if rule is None:
        return None, damage_range
    return rule, DamageRange.union(rule.damage_range(), damage_range)
