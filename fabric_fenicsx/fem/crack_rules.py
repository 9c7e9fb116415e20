"""The crack-tracking failure rules by name (``material.failure``, ``study tear --failure``)."""
from __future__ import annotations

from fabric_fenicsx.fem.shear_lag import SLIP_CONCENTRATION, ShearLag
from fabric_fenicsx.fem.yarn_crack import YarnCrack
from fabric_fenicsx.fem.yarn_tip import YarnTip

__all__ = ["CRACK_RULES", "crack_rule_on_cells"]

_DEL_ZONE = {"concentration_cap": SLIP_CONCENTRATION, "snap": True, "band": 3.0, "close_bridges": True,
             "read_uncut": True}

CRACK_RULES = {"yarn_crack": (YarnCrack, {}), "yarn_tip": (YarnTip, {}), "yarn_strain": (YarnTip, {"roots": True}),
               "shear_lag": (ShearLag, {}), "del_zone": (ShearLag, _DEL_ZONE),
               "del_zone_budget": (ShearLag, {**_DEL_ZONE, "budget": True})}
"""Name -> (class, options): the yarn crack (:mod:`~fabric_fenicsx.fem.yarn_crack`), its tip that
reads its yarn (:mod:`~fabric_fenicsx.fem.yarn_tip`; ``yarn_strain``: its start too), and its tip
that breaks by Hedgepeth's concentration of its yarn (:mod:`~fabric_fenicsx.fem.shear_lag`;
``del_zone``: that concentration at most :data:`~fabric_fenicsx.fem.shear_lag.SLIP_CONCENTRATION`,
the crossings slipping, its crack cells snapping, its yarn read over the uncut yarns of three
rows and its cracks' bridges cut, :mod:`~fabric_fenicsx.fem.crack_bridges`; ``del_zone_budget``:
its snapped cells held at alpha 1/2 until they break through with one segment's work per yarn,
:mod:`~fabric_fenicsx.fem.crack_budget`)."""


def crack_rule_on_cells(name: str, corners, directions, fabric, points_per_cell: int = 1, laws=None, comm=None):
    """The crack-tracking rule ``name`` (:data:`CRACK_RULES`) over cells, as
    :meth:`YarnCrack.on_cells <fabric_fenicsx.fem.yarn_crack.YarnCrack.on_cells>`."""
    kind, options = CRACK_RULES[name]
    return kind.on_cells(corners, directions, fabric, points_per_cell, laws, comm, **options)
