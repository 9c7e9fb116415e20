"""The cases of the stability study (:mod:`fabric_fenicsx.studies.stability`): the base scene
and its coarse, short overrides, the case list, the fabric variants a case may run with, and the
settings that decide whether a stored result of a case is reused. Nothing heavy is imported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

# ============================================================================ the cases
BASE_SCENE = "demos/scenes/y90.toml"
BASE_OVERRIDES = (
    "mesh.h_centre=0.004",          # coarser than the scene's 1.41 mm: fast cases
    "mesh.h_edge=0.012",
    "run.t_end=0.0006",             # 0.6 ms: at 57.3 m/s yarn damage starts at about 0.49 ms
    "output.xdmf_interval=0",
    "output.png=false",
    "output.progress_interval=0",
)
"""Coarse, short version of the Y90 scene every case starts from, with the scene's element (the
reduced one: one point per cell and hourglass control, docs/mesh_independence.md)."""

CANONICAL_COMMAND = (".venv/bin/python -m fabric_fenicsx.studies.stability --out out/stability "
                     "--doc docs/stability.md --rerun")
"""The command that runs the whole study from scratch and writes docs/stability.md."""

ENERGY_LIMIT = 0.05
"""Energy-balance error the issue allows (also the scene default of run.energy_tolerance)."""

SIDE = 0.27305
EDGE_DISTANCE = 0.020
EDGE_Y = -(SIDE / 2 - EDGE_DISTANCE)
"""Impact point 20 mm from the clamped bottom edge (y = -side/2) of the Y90 fabric."""

BLOW_UP_RATIO = 1.2
"""Kinetic energy above this multiple of KE_0 in history.csv = a blow-up (impact.py's guard)."""


@dataclass(frozen=True)
class Case:
    """One stability case.

    name: folder and CSV name; title: the issue's wording; overrides: scene overrides on top
    of :data:`BASE_OVERRIDES`; fabric: ``(kind, value)`` for :func:`make_fabric` or None (the
    scene's built-in fabric); purpose: what the case probes.
    """

    name: str
    title: str
    overrides: tuple[str, ...] = ()
    fabric: tuple[str, float] | None = None
    purpose: str = ""


CASES: tuple[Case, ...] = (
    Case("fillet-0", "fillet 0 (= the base scene)", ("projectile.fillet=0.0",),
         purpose="sharp-edged projectile: the Y90 scene's own fillet is 0, so this is also the "
                 "reference the other cases differ from"),
    Case("bending-x10", "bending stiffness x10", fabric=("bending", 10.0),
         purpose="B0 of both yarns x 10: a stiffer crimp interchange, a stiffer initial response"),
    Case("bending-div10", "bending stiffness /10", fabric=("bending", 0.1),
         purpose="B0 of both yarns / 10: a nearly free crimp interchange (soft start, then the "
                 "straight-yarn stiffness)"),
    Case("stretch-x10", "stretch stiffness x10", fabric=("stretch", 10.0),
         purpose="A0 of both yarns x 10: wave speed x ~3, so dt / ~3"),
    Case("crimp-0", "crimp 0 %", fabric=("crimp", 0.0),
         purpose="straight yarns (Phi_L = 0, L = w, yarn spacing kept): a degenerate unit cell "
                 "with no height and no contact force"),
    Case("crimp-10", "crimp 10 %", fabric=("crimp", 0.10),
         purpose="both yarns at 10 % crimp (Phi_L from the crimp, L = 1.1 w, yarn spacing kept): "
                 "a long, soft de-crimping phase"),
    Case("v300", "projectile at 300 m/s", ("projectile.velocity=300.0",),
         purpose="fast impact: large strain rates, early perforation"),
    Case("v1000", "projectile at 1000 m/s", ("projectile.velocity=1000.0",),
         purpose="very fast impact: the projectile moves ~0.2 mm per step, comparable to the "
                 "contact penetration"),
    Case("friction-0", "friction 0", ("projectile.friction=0.0",),
         purpose="frictionless contact"),
    Case("friction-2", "friction 2.0", ("projectile.friction=2.0",),
         purpose="high friction (Sec. 4.4.1): sticking nodes under the face"),
    Case("angle-30", "yarns at 30 degrees", ("material.angle=30.0",),
         purpose="warp at 30 degrees from global X (two clamped edges not aligned with the yarns)"),
    Case("edge-20mm", "impact 20 mm from a clamped edge", (f"projectile.y={EDGE_Y!r}",),
         purpose="impact point 20 mm from the clamped bottom edge (the projectile's rim 7.3 mm "
                 "from it): short, stiff yarns to the support; the graded mesh is fine there"),
    Case("refined-4x", "mesh refined 4 x near the impact",
         ("mesh.h_centre=0.001", "run.t_end=0.0003"),
         purpose="h_centre 1 mm (4 x finer than the base 4 mm) with t_end 0.3 ms: dt / 4, "
                 "more cells under the face"),
    Case("beyond-table", "strains beyond the surrogate's table",
         ("material.damage=false", "projectile.velocity=300.0"),
         purpose="damage off at 300 m/s: intact yarns are stretched past the table's upper end "
                 "(the lookup clips there, a constant stress)"),
    Case("large-damage", "a large fully damaged region",
         ("projectile.diameter=0.1", "projectile.velocity=300.0"),
         purpose="a 100 mm projectile at 300 m/s (mass kept): yarns break over a wide zone and "
                 "many cells are removed"),
)


# ============================================================================ fabrics
def scaled_stiffness(fabric, stretch: float = 1.0, bending: float = 1.0):
    """The fabric with A0 of both yarns x ``stretch`` and B0 x ``bending``."""
    for name, x in (("stretch", stretch), ("bending", bending)):
        if not (math.isfinite(x) and x > 0):
            raise ValueError(f"{name} factor must be positive and finite, got {x!r}")
    out = fabric
    for which in ("warp", "fill"):
        y = getattr(out, which)
        out = out.with_yarn(which, A0=y.A0 * stretch, B0=y.B0 * bending)
    return out


def _yarn_with_crimp(yarn, crimp: float):
    """The yarn with degree of crimp ``crimp`` (L/w - 1) at the same projected half-length w
    (yarn spacing 2 w kept): Phi_L solves crimp(Phi_L) = crimp (the crimp of the shape of
    Eq. 3-5 depends on Phi_L only), then L = w (1 + crimp)."""
    from scipy.optimize import brentq

    w = yarn.w
    if crimp == 0.0:
        return yarn.scaled(Phi_L=0.0, L=w)
    hi = math.pi / 2 - 1e-6
    top = yarn.scaled(Phi_L=hi).crimp
    if not 0.0 < crimp < top:
        raise ValueError(f"crimp must lie in [0, {top:.4f}) for the shape of Eq. 3-5, got {crimp!r}")
    phi = brentq(lambda p: yarn.scaled(Phi_L=p).crimp - crimp, 0.0, hi, xtol=1e-14)
    return yarn.scaled(Phi_L=phi, L=w * (1.0 + crimp))


def with_crimp(fabric, crimp: float):
    """The fabric with both yarns at degree of crimp ``crimp``, yarn spacing kept."""
    if not (math.isfinite(crimp) and crimp >= 0):
        raise ValueError(f"crimp must be a finite number >= 0, got {crimp!r}")
    return fabric.replace(warp=_yarn_with_crimp(fabric.warp, crimp),
                          fill=_yarn_with_crimp(fabric.fill, crimp))


def make_fabric(spec: tuple[str, float], bending_bound: str = "max"):
    """The fabric of a case: ``("bending" | "stretch", factor)`` or ``("crimp", crimp)``
    applied to the built-in Zylon AS (Table 1) with the scene's bending bound."""
    from fabric_fenicsx.material.fabric import zylon_as

    kind, value = spec
    base = zylon_as(bending=bending_bound)
    if kind == "bending":
        fab = scaled_stiffness(base, bending=value)
        label = f"B0 x {value:g}"
    elif kind == "stretch":
        fab = scaled_stiffness(base, stretch=value)
        label = f"A0 x {value:g}"
    elif kind == "crimp":
        fab = with_crimp(base, value)
        label = f"crimp {100 * value:g} %"
    else:
        raise ValueError(f"unknown fabric change {kind!r}; valid: bending, stretch, crimp")
    return fab.replace(name=f"{base.name}, {label}")


# ============================================================================ one case
def case_settings(case: Case, base_scene: str = BASE_SCENE,
                  base_overrides: tuple[str, ...] = BASE_OVERRIDES) -> dict:
    """What determines a case's result (compared before a case is skipped), the base scene
    file's content included (an edit of its defaults re-runs the cases)."""
    import hashlib
    fab = make_fabric(case.fabric).to_dict() if case.fabric else None
    text = Path(base_scene).read_bytes() if Path(base_scene).is_file() else b""
    return {"base_scene": str(base_scene), "base_scene_sha256": hashlib.sha256(text).hexdigest()[:12],
            "overrides": list(base_overrides) + list(case.overrides), "fabric": fab}
