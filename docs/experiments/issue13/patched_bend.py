"""Adds a linear plate-bending term D/2 int (Laplacian u_z)^2 dA (discrete: u_z^T K M^-1 K u_z,
K the Q1 Laplacian, M lumped, on the reference mesh; serial only). BEND_D: D in N m
(default: the warp's B0 x yarns per metre). BEND_CABLE=1: the cable material too;
PLUG=1: the bonded plug too."""
import os, sys, numpy as np, scipy.sparse as sp
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
import fabric_fenicsx.impact.simulation as simmod
from fabric_fenicsx.fem.terms import MembraneTerm
from fabric_fenicsx.material.fabric import zylon_as
f0 = zylon_as()
D = float(os.environ.get("BEND_D", f0.warp.B0 * f0.yarns_per_metre))
if os.environ.get("BEND_CABLE") == "1":
    exec(open("/work/ens/patched_cable.py").read().split("from fabric_fenicsx.cli")[0])
if os.environ.get("PLUG") == "1":
    os.environ["PLUG_UNIT"] = "1"   # plug only; the material is chosen above
    exec(open("/work/ens/patched_plug.py").read().split("from fabric_fenicsx.cli")[0])
class BendingZ(MembraneTerm):
    name = "bending"; per_cell = True
    def __init__(self, D):
        self.D = D; self.B = None
    def prepare(self, m):
        if self.B is not None:
            return
        Vz, idx = m.V.sub(2).collapse()
        u, v = ufl.TrialFunction(Vz), ufl.TestFunction(Vz)
        A = fem_petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx))
        A.assemble()
        ai, aj, av = A.getValuesCSR()
        K = sp.csr_matrix((av, aj, ai), shape=A.getSize())
        ml = fem_petsc.assemble_vector(fem.form(v * ufl.dx)).array
        self.idx = np.asarray(idx)
        self.B = (K @ sp.diags(1.0 / ml) @ K).tocsr() * self.D
    def add_cell_forces(self, m, forces):
        uz = m.u.x.array[self.idx]
        f = self.B @ uz
        forces.reshape(-1)[self.idx] += f
        return 0.5 * float(uz @ f)
_orig = simmod.build_terms
def build_terms(scene, k):
    return [*_orig(scene, k), BendingZ(D)]
simmod.build_terms = build_terms
from fabric_fenicsx.cli import main
sys.exit(main(sys.argv[1:]))
