"""The unit-cell surrogate: a table of the unit cell's response over the membrane strains (E1, E2)
and the yarns' integrity ratio, built tile by tile where a scene visits and cached on disk
(:mod:`~fabric_fenicsx.surrogate.tiles`), interpolated (:mod:`~fabric_fenicsx.surrogate.interp`)
by compiled kernels (:mod:`~fabric_fenicsx.surrogate.kernels`). No DOLFINx."""
from fabric_fenicsx.surrogate.table import Surrogate, SurrogateError, lambda_tangent, material_point

__all__ = ["Surrogate", "SurrogateError", "lambda_tangent", "material_point"]
