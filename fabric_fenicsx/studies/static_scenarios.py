"""The static material-point scenes (:mod:`fabric_fenicsx.studies.static`): their names, the
constants of their strain paths, the step budget known before a scene runs and the bending
scene's bounds. Nothing here imports DOLFINx.
"""

from __future__ import annotations

import math

from fabric_fenicsx.material.fabric import Fabric, zylon_as

SCENARIOS = ("uniaxial-strain", "load-unload", "equibiaxial", "uniaxial-stress", "bending")
COLUMNS = ("E1", "E2", "P1", "P2", "alpha1", "alpha2", "V")
"""CSV columns of every scene (SI: P in N/m, V in N); load-unload adds ``leg``, bending ``B2``."""

DEFAULT_STEP = 0.0005
E1_CAP = 0.15
"""Hard cap on E1: a path that has not failed completely by then stops and says so."""
EXTRA_STEPS = 5
"""Steps recorded after complete failure, to show the flat tail."""
UNLOAD_E1 = 0.054
"""Unloading point of scenario 2: past the P1 peak (E1 ~ 0.049), warp partially damaged."""
BENDING_RATIO = 5.0
"""Lower end of the E2 search in the free-fill root find (E > -0.5 for any stretch)."""
LEGS = ("load", "unload", "reload")
MAX_STEPS = 200_000
"""Default limit on a scene's E1 steps (material-point solves; :func:`estimate_steps`). One step
takes about 15-20 ms on one core (measured, unit cell), so this is about an hour; the default
step gives a few hundred steps, and a step below ~1e-6 resolves nothing the figures show."""

_LOADED = {  # yarns whose complete failure ends a monotone path (0 = warp, 1 = fill)
    "uniaxial-strain": (0,), "load-unload": (0,), "equibiaxial": (0, 1),
    "uniaxial-stress": (0,), "bending": (0,),
}
_TITLES = {
    "uniaxial-strain": "Scenario 1: uniaxial strain, E2 = 0",
    "load-unload": "Scenario 2: load, unload, reload, E2 = 0",
    "equibiaxial": "Scenario 3: equibiaxial strain, E1 = E2",
    "uniaxial-stress": "Scenario 4: uniaxial stress, P2 = 0",
    "bending": "Scenario 4 with B2 at its upper and lower bound",
}


# ----------------------------------------------------------------------------- scenarios
def check_step(step) -> float:
    """``step`` as a float, or a ValueError unless it is a finite number in (0, E1_CAP]."""
    try:
        s = float(step)
    except (TypeError, ValueError):
        raise ValueError(f"step must be a positive number, got {step!r}") from None
    if not math.isfinite(s) or s <= 0.0 or s > E1_CAP:
        raise ValueError(f"step must be a finite number in (0, {E1_CAP}], got {step!r}")
    return s


def estimate_steps(name: str, fabric: Fabric | None, step: float, unload_at: float = UNLOAD_E1) -> int:
    """An upper bound of the E1 steps (material-point solves) scene ``name`` takes at ``step``,
    known before it runs: its CSV rows plus, for load-unload, the reference monotone path.

    A monotone path (:func:`_path_steps`) ends EXTRA_STEPS after the loaded yarns' complete
    failure. load-unload adds its load and unload legs to unload_at and the reference path;
    bending runs two paths. The bound is about 1.4 times the steps taken for Zylon AS."""
    path = _path_steps(name, fabric, step)
    if name == "load-unload":
        leg = math.floor(unload_at / step + 1e-9) + 2  # the grid and unload_at itself
        return leg + (leg - 1) + 2 * path
    return 2 * path if name == "bending" else path


def _path_steps(name: str, fabric: Fabric | None, step: float) -> int:
    """Steps of one monotone path, at most: complete failure of the loaded yarns comes at the
    latest at the first grid point at or beyond E1 = E_fail = ((mu_complete L / w)^2 - 1) / 2
    (a yarn is at least as stretched as its projection, lambda w / L; mu_complete from the
    damage law; the crimp is pulled out before, so the path ends earlier), then EXTRA_STEPS
    more; and at E1_CAP in any case."""
    base = zylon_as("max") if fabric is None else fabric
    law = base.damage
    E_fail = [0.5 * ((law.mu_complete(y.mu_crit) * y.L / y.w) ** 2 - 1.0) for y in base.yarns]
    E_end = max(E_fail[i] for i in _LOADED[name])
    return min(math.ceil(E_end / step - 1e-9) + EXTRA_STEPS, math.floor(E1_CAP / step + 1e-9)) + 1


def check_budget(name: str, fabric: Fabric | None, step: float, max_steps: int | None = MAX_STEPS,
                 unload_at: float = UNLOAD_E1) -> int:
    """:func:`estimate_steps`, or a ValueError if it exceeds ``max_steps`` (None: no limit) that
    gives the estimate, its time and the smallest step within the limit."""
    n = estimate_steps(name, fabric, step, unload_at)
    if max_steps is not None and n > max_steps:
        smallest = step * n / max_steps
        raise ValueError(
            f"--step {step:g}: scene {name} would take up to {n:,} steps (material-point solves), "
            f"about {_duration(n * 0.018)} at ~18 ms each, more than the limit of {max_steps:,}; "
            f"use --step {_round_up(smallest)} or larger (default {DEFAULT_STEP:g}), or raise the limit "
            f"with --max-steps")
    return n


def _duration(seconds: float) -> str:
    """``seconds`` in the largest unit that gives at least 2 of it."""
    for unit, size in (("days", 86400.0), ("hours", 3600.0), ("minutes", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.0f} {unit}"
    return f"{seconds:.0f} s"


def _round_up(x: float) -> str:
    """``x`` rounded up to two significant digits, as text."""
    exponent = math.floor(math.log10(x)) - 1
    return f"{math.ceil(x / 10.0 ** exponent - 1e-9) * 10.0 ** exponent:.2g}"


def bending_bounds(fabric: Fabric | None = None) -> tuple[float, float]:
    """Upper and lower bound of the fill's bending stiffness B2 (N m^2) for the bending scene.

    Table 1 of the thesis (``fabric=None``, Zylon AS); for another fabric its fill's B0 is the
    upper bound and B0 / BENDING_RATIO the lower (section 3.2: "five times the minimum").
    """
    if fabric is None:
        return zylon_as("max").fill.B0, zylon_as("min").fill.B0
    return fabric.fill.B0, fabric.fill.B0 / BENDING_RATIO
