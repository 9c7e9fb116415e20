"""Work of a unit cell up to and through its damage softening, and what a crack band could do.

The mesh-independence study (docs/mesh_independence.md) asked whether a crack band (the
softening branch of alpha(mu), Eq. 2-25, shortened in cells longer than a fabric length l) would
make the energy of a tear independent of the cell size. In a cell of length h across the tear that energy is h x (the work per reference area to
break the cell), W = W_pre + W_soft(s): W_pre up to damage onset, W_soft over the softening
branch shortened by s. A crack band needs h W(s) = l W(1), which has a solution s in (0, 1]
only if h W_pre < l W(1).

:func:`softening_work` loads a material point along the warp in uniaxial strain (E2 = 0, the
thesis's scenario 1) through complete failure with the surrogate's damage update and the
shortened law (:func:`fabric_fenicsx.material.fibril.crack_band_alpha`) and returns W_pre and
W_soft. Run ``python -m fabric_fenicsx.studies.softening`` for the table of
docs/mesh_independence.md. No DOLFINx.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SofteningWork", "softening_work", "main"]


@dataclass(frozen=True)
class SofteningWork:
    """Work per reference area (J/m^2) of the warp loaded in uniaxial strain: ``pre`` up to
    damage onset (E1 = ``E_onset``), ``soft`` from there to complete failure (E1 =
    ``E_failure``), with the softening branch shortened by ``scale``."""
    scale: float
    E_onset: float
    E_failure: float
    pre: float
    soft: float


def softening_work(surrogate, scale: float = 1.0, E_max: float = 0.08, steps: int = 3200) -> SofteningWork:
    """:class:`SofteningWork` of ``surrogate``'s fabric at crack-band ``scale`` (warp only),
    E1 from 0 to ``E_max`` in ``steps`` equal increments, E2 = 0, damage updated every step
    (Eq. 2-25 with history); trapezoidal work sum P1 d lambda1."""
    if not 0.0 < scale <= 1.0:
        raise ValueError(f"scale must lie in (0, 1], got {scale!r}")
    E1 = np.linspace(0.0, E_max, steps + 1)
    P1, alpha1 = np.empty_like(E1), np.empty_like(E1)
    a1 = a2 = 1.0
    for k, e in enumerate(E1):        # a path: each step starts from the last one's damage
        p1, _, a1, a2 = surrogate.update(e, 0.0, a1, a2, crack_band=(scale, 1.0))
        P1[k], alpha1[k] = float(p1), float(a1)
    if alpha1[-1] > 0.0:
        raise ValueError(f"the warp did not fail completely by E1 = {E_max}; raise E_max")
    lam = np.sqrt(1.0 + 2.0 * E1)
    onset = int(np.argmax(alpha1 < 1.0))          # first damaged state
    failure = int(np.argmax(alpha1 == 0.0))
    work = np.concatenate(([0.0], np.cumsum(0.5 * (P1[1:] + P1[:-1]) * np.diff(lam))))
    return SofteningWork(scale, float(E1[onset]), float(E1[failure]), float(work[onset - 1]),
                         float(work[failure] - work[onset - 1]))


def main(scales=(1.0, 0.9, 0.8, 0.7, 0.6, 0.5)) -> None:
    """Print the table for the default Zylon AS table (bending at its upper bound)."""
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.surrogate.table import Surrogate

    sur = Surrogate(zylon_as("max"))
    print("scale  E1 onset  E1 failure  W_pre (J/m^2)  W_soft (J/m^2)  W_soft / scale")
    for s in scales:
        w = softening_work(sur, s)
        print(f"{s:5.2f}  {w.E_onset:8.4f}  {w.E_failure:10.4f}  {w.pre:13.1f}  {w.soft:14.1f}  {w.soft / s:14.1f}")


if __name__ == "__main__":
    main()
