"""When an impact run re-checks its time step, and the record of each lowering.

The rule itself, the damped Courant limit, is :func:`fabric_fenicsx.fem.timestep.stable_dt`
(re-exported here with its helpers); the run asks it through
:meth:`fabric_fenicsx.fem.explicit.CentralDifference.stable_dt`, so the integrator, the loop
and their messages quote one step. dt is only ever lowered; see docs/impact_model.md.
"""
from __future__ import annotations

from dataclasses import dataclass

from fabric_fenicsx.fem.timestep import (damping_coefficient, highest_frequency, stable_dt,
                                         unit_cell_frequency, unit_cell_length)

__all__ = ["DtChange", "stable_dt", "check_due", "highest_frequency", "unit_cell_length",
           "unit_cell_frequency", "damping_coefficient"]


@dataclass
class DtChange:
    """A lowering of the time step (summary ``dt_changes``)."""
    step: int
    time: float
    dt_old: float
    dt_new: float
    modulus: float


def check_due(step: int, step_touch: int | None, interval: int) -> bool:
    """Re-check dt every ``interval`` steps, and at every step of the first ``interval`` after
    the first touch (the strain increments the look-ahead extrapolates are not known before)."""
    return step > 0 and (step % interval == 0 or (
        step_touch is not None and step - step_touch <= interval))
