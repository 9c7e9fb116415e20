"""Material scale: fabric parameters (Table 1), fibril damage laws (Eq. 2-22 to 2-25), the yarn
unit cell (Eq. 2-17 to 2-31, appendix), the damage coupling alpha = alpha(mu(alpha)) and the
material-point contract every constitutive law of the package implements. No DOLFINx."""
from fabric_fenicsx.material.contract import DamageState, MaterialLaw, MaterialPoint, QuadratureMaterial
from fabric_fenicsx.material.damage_solver import DamageIterationError
from fabric_fenicsx.material.fabric import Fabric, Yarn, zylon_as
from fabric_fenicsx.material.fibril import BundleDamage, ExponentialDamage, FibrilBundle, damage_law_from_dict
from fabric_fenicsx.material.unitcell import ALPHA_BROKEN, UnitCell, UnitCellError, UnitCellResult

__all__ = ["Fabric", "Yarn", "zylon_as", "ExponentialDamage", "BundleDamage", "FibrilBundle",
           "damage_law_from_dict", "UnitCell", "UnitCellError", "UnitCellResult", "ALPHA_BROKEN",
           "DamageIterationError", "DamageState", "MaterialLaw", "MaterialPoint", "QuadratureMaterial"]
