"""Messages of an impact run that stops on numerical trouble: which component failed (the
membrane, the unit cell while solving a table tile, a table tile), where, and what can help."""
from __future__ import annotations

import numpy as np

from fabric_fenicsx.material.unitcell import UnitCellError
from fabric_fenicsx.surrogate.table import SurrogateError

__all__ = ["STEP_ERRORS", "component", "fixes", "place"]

STEP_ERRORS = (FloatingPointError, ValueError, SurrogateError, UnitCellError)
"""Errors of a step that mean numerical trouble, not a bug."""


def component(err: BaseException) -> str:
    """The component an error of a step comes from: the surrogate's table (a tile), the
    unit cell (solving a tile) or the membrane (its step: non-finite or invalid values)."""
    if isinstance(err, SurrogateError):
        return "table tile"
    if isinstance(err, UnitCellError):
        return "unit cell"
    return "membrane"


def fixes(which: str, cache_dir) -> str:
    """What can help when ``which`` failed; only settings that change it."""
    not_dt = "the time step is not the cause"
    if which == "table tile":
        return (f"{not_dt}; a table tile of the surrogate cache holds bad values: delete "
                f"{cache_dir} so that its tiles are solved again")
    if which == "unit cell":
        return (f"{not_dt}; the unit cell did not converge while solving a table tile at the "
                f"strains above: check the fabric's values (fabric.file)")
    return ("Likely fixes: lower run.dt_safety, raise run.damping, lower projectile.penalty_fraction, "
            "or refine the mesh at the impact point (mesh.h_centre)")


def place(u: np.ndarray, X: np.ndarray, rank: int, among: np.ndarray | None = None, what: str = "") -> str:
    """Where the trouble is: the first node with a non-finite displacement, else the node that
    moved most (``u`` and reference coordinates ``X`` of this rank's owned nodes, (n, 3)), among
    the nodes of the mask ``among`` if given (``what`` names them)."""
    bad = np.flatnonzero(~np.all(np.isfinite(u), axis=1))
    if bad.size:
        return f"first non-finite node at reference (x, y) = {X[bad[0], :2]} m on rank {rank}"
    candidates = np.arange(len(u)) if among is None else np.flatnonzero(among[:len(u)])
    if not candidates.size:
        return f"no owned {what or 'nodes'} on rank {rank}"
    k = int(candidates[np.argmax(np.abs(u[candidates]).max(axis=1))])
    return (f"largest displacement{f' of {what}' if what else ''} {u[k]} m at reference (x, y) = {X[k, :2]} m "
            f"on rank {rank}")


def attached_reach(side: float, erosion_strain: float | None) -> float:
    """How far fabric still attached to a clamped edge can move before a move means a blow-up
    (m). Without removal (damage off) the fabric stays whole: its side. With removal a piece
    torn from one clamp hangs from another and swings; it is joined to that clamp by a path of
    fabric taken as at most two sides long, every cell of it stretched at most to the erosion
    strain (stretch sqrt(1 + 2 E)): the piece reaches 2 side (1 + sqrt(1 + 2 E))."""
    if erosion_strain is None:
        return side
    return 2.0 * side * (1.0 + np.sqrt(1.0 + 2.0 * erosion_strain))
