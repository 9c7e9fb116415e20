"""The material-point contract (fabric_fenicsx.material.contract): who implements which shape,
and the unit cell and its surrogate answering the same question through it alike."""
import numpy as np
import pytest

from fabric_fenicsx.fem.explicit import LinearYarnMaterial
from fabric_fenicsx.fem.yarn_stress import YarnStress
from fabric_fenicsx.material import DamageState, MaterialLaw, MaterialPoint, QuadratureMaterial
from fabric_fenicsx.studies.static import UnitCellPoint


@pytest.fixture(scope="module")
def laws(coarse_surrogate):
    """The unit cell and the session's coarse table of the same fabric."""
    return UnitCellPoint(coarse_surrogate.fabric), coarse_surrogate


def test_each_law_implements_its_shapes_of_the_contract(laws):
    cell, sur = laws
    for law in (cell, sur, LinearYarnMaterial(1.0, 1.0)):
        assert isinstance(law, MaterialLaw)
    assert isinstance(cell, MaterialPoint) and isinstance(sur, MaterialPoint)
    adapter = YarnStress(sur, np.ones(4), damage=True)
    for material in (adapter, LinearYarnMaterial(1.0, 1.0)):
        assert isinstance(material, QuadratureMaterial)
    assert not isinstance(sur, QuadratureMaterial)          # it keeps no history of its own
    assert not isinstance(object(), MaterialLaw)


def test_removed_points_are_those_with_both_yarns_broken():
    state = DamageState(np.array([0.0, 0.0, 0.3, 1.0]), np.array([0.0, 0.2, 0.0, 1.0]))
    assert state.removed.tolist() == [True, False, False, False]
    assert not DamageState.intact(3).removed.any()


def test_unit_cell_and_surrogate_agree_through_the_contract(laws):
    """Same strains, same history: stresses within 0.5 % of the largest (the default table's
    acceptance; measured on the coarse table: 0.16 %), the same new damage, wave moduli within
    0.5 % (measured: 0.24 %). The unit cell's wave modulus comes from central differences of its
    own solve, independent of the table's interpolant."""
    cell, sur = laws
    E1, E2 = np.array([0.01, 0.02, 0.045, 0.05]), np.array([0.01, 0.03, 0.01, 0.05])
    history = DamageState(np.array([1.0, 0.6, 1.0, 0.3]), np.array([1.0, 1.0, 0.5, 0.3]))
    Pc1, Pc2, new_c = cell.constitutive_update(E1, E2, history)
    Ps1, Ps2, new_s = sur.constitutive_update(E1, E2, history)
    scale = max(np.abs(Pc1).max(), np.abs(Pc2).max())
    assert np.abs(Ps1 - Pc1).max() < 5e-3 * scale and np.abs(Ps2 - Pc2).max() < 5e-3 * scale
    assert np.allclose(new_s.alpha1, new_c.alpha1, atol=1e-6)
    assert np.allclose(new_s.alpha2, new_c.alpha2, atol=1e-6)
    assert new_c.alpha2[3] == 0.0 and new_c.alpha1[3] > 0       # the fill breaks at E = 0.05
    assert np.all(new_c.alpha1 <= history.alpha1) and np.all(new_c.alpha2 <= history.alpha2)
    w_cell, w_sur = cell.wave_modulus(E1, E2, new_c), sur.wave_modulus(E1, E2, new_c)
    assert np.all(w_cell > 0)
    assert np.allclose(w_sur, w_cell, rtol=5e-3)
