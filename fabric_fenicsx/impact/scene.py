"""Impact scene files: TOML schema, defaults, validation and ``--set section.key=value`` overrides.

A scene describes one ballistic impact of the thesis's chapter 4: the fabric, its material
orientation and damage switch, the mesh, the projectile (Sec. 4.1, 4.4.3), the clamped edges
(Table 3) and the run and output controls. Every key has a default, so a scene file only
states what differs; ``demos/scenes/{y0,y90,xy0,xy45}.toml`` are the four set-ups named as in
Table 3. Units are SI (m, kg, s, m/s); the material angle is in degrees.

Validation happens before any work: an unknown section or key, a value of the wrong type or
out of range, a scene path that is a folder or not UTF-8 text, a fabric file (``fabric.file``)
that is missing or invalid, raises :class:`SceneError` with a message listing what is valid;
an output folder that cannot be written raises :class:`InputError`
(:func:`check_output_dir`). Nothing here imports DOLFINx.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import tempfile
import tomllib
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable

from fabric_fenicsx.impact.term_specs import check_term_specs, resolve_term_specs

__all__ = ["InputError", "SceneError", "Scene", "SCHEMA", "EDGES", "FIELDS", "SCATTER_FIELDS", "load_scene", "load_fabric",
           "check_output_dir", "parse_override", "describe_schema", "locking_warning", "ignored_keys_warning",
           "yarns_follow_the_mesh"]

EDGES = ("left", "right", "bottom", "top")
"""Edge names: x = -side/2, x = +side/2, y = -side/2, y = +side/2 (global X-Y, Table 3)."""

FIELDS = ("displacement", "velocity", "P1", "P2", "E1", "E2", "SDV1", "SDV2", "SDV3", "mu_crit1", "mu_crit2")
SCATTER_FIELDS = ("mu_crit1", "mu_crit2")
"""Cell fields of a strength scatter (each cell's warp and fill critical stretch, written with
``material.scatter`` on only)."""
"""Fields the XDMF time series can hold: nodal displacement and velocity, and cell-wise
(area-weighted cell averages of the quadrature points) yarn stresses P1, P2 (N/m), yarn
strains E1, E2 and the state variables of Table 2 (SDV1 = 0 for a removed cell)."""

FABRICS = ("zylon_as",)


class InputError(ValueError):
    """An input of a run (scene, fabric file, output folder) is unusable; the message names it
    and says what is valid."""


class SceneError(InputError):
    """A scene file, an override or the fabric file it names is invalid; the message says what
    is valid."""


@dataclasses.dataclass(frozen=True)
class Key:
    """One scene key: its default, a converter/validator and a one-line meaning."""

    default: Any
    check: Callable[[str, Any], Any]
    doc: str


# ----------------------------------------------------------------------------- checkers
def _type_name(value: Any) -> str:
    return type(value).__name__


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{name} = {value!r} ({_type_name(value)}): must be a number")
    x = float(value)
    if not math.isfinite(x):
        raise SceneError(f"{name} = {value!r}: must be finite")
    return x


def number(lo: float | None = None, hi: float | None = None, lo_open: bool = False,
           hi_open: bool = False, unit: str = "") -> Callable[[str, Any], float]:
    def check(name: str, value: Any) -> float:
        x = _number(name, value)
        bad_lo = lo is not None and (x <= lo if lo_open else x < lo)
        bad_hi = hi is not None and (x >= hi if hi_open else x > hi)
        if bad_lo or bad_hi:
            left = "-inf" if lo is None else f"{lo:g}"
            right = "inf" if hi is None else f"{hi:g}"
            interval = f"{'(' if lo_open or lo is None else '['}{left}, {right}{')' if hi_open or hi is None else ']'}"
            raise SceneError(f"{name} = {value!r}: must lie in {interval}{' ' + unit if unit else ''}")
        return x
    check.kind = f"number{' (' + unit + ')' if unit else ''}"
    return check


def integer(lo: int = 0) -> Callable[[str, Any], int]:
    def check(name: str, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(f"{name} = {value!r} ({_type_name(value)}): must be an integer")
        if value < lo:
            raise SceneError(f"{name} = {value!r}: must be an integer >= {lo}")
        return int(value)
    check.kind = f"integer >= {lo}"
    return check


def boolean(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise SceneError(f"{name} = {value!r} ({_type_name(value)}): must be true or false")
    return value


boolean.kind = "true/false"


def choice(*options: str) -> Callable[[str, Any], str]:
    def check(name: str, value: Any) -> str:
        if value not in options:
            raise SceneError(f"{name} = {value!r}: must be one of {list(options)}")
        return value
    check.kind = " | ".join(options)
    return check


def optional_text(name: str, value: Any) -> str:
    if not isinstance(value, str):
        raise SceneError(f"{name} = {value!r} ({_type_name(value)}): must be a string (\"\" for none)")
    return value


optional_text.kind = "string"


def subset(options: tuple[str, ...], allow_empty: bool = False) -> Callable[[str, Any], list[str]]:
    def check(name: str, value: Any) -> list[str]:
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise SceneError(f"{name} = {value!r}: must be a list of names from {list(options)}")
        bad = [v for v in value if v not in options]
        if bad:
            raise SceneError(f"{name} = {value!r}: unknown {bad}; valid names are {list(options)}")
        if len(set(value)) != len(value):
            raise SceneError(f"{name} = {value!r}: names must not repeat")
        if not value and not allow_empty:
            raise SceneError(f"{name} = []: needs at least one of {list(options)}")
        return list(value)
    check.kind = f"list from {list(options)}"
    return check


# ----------------------------------------------------------------------------- schema
SCHEMA: dict[str, dict[str, Key]] = {
    "fabric": {
        "name": Key("zylon_as", choice(*FABRICS),
                    "built-in fabric: zylon_as = 500 denier PBO Zylon AS, Table 1"),
        "file": Key("", optional_text,
                    "TOML fabric file (fabric_fenicsx.material.fabric.Fabric.load) used instead of name; "
                    "relative to the scene file (to the working folder without one); checked before any work"),
        "bending": Key("max", choice("max", "min"),
                       "bending stiffness bound of the built-in fabric (Table 1, Sec. 3.2)"),
    },
    "material": {
        "angle": Key(0.0, number(-360.0, 360.0, unit="deg"),
                     "warp (yarn 1) direction from global X, degrees (Table 3: 0 for Y0/XY0, "
                     "90 for Y90, 45 for XY45)"),
        "damage": Key(True, boolean,
                      "damage evolution (Eq. 2-25) and cell deletion; false = intact yarns, the "
                      "surrogate is asked with alpha = 1 only"),
        "erosion_strain": Key(1.0, number(0.0, lo_open=True),
                              "Green strain of a yarn direction beyond which a cell is eroded "
                              "(no longer a unit cell; see docs/impact_model.md)"),
        "failure": Key("thesis", choice("thesis", "yarn_crack", "yarn_tip", "yarn_strain", "shear_lag", "del_zone",
                                        "del_zone_budget"),
                       "failure rule (fabric_fenicsx.impact.setup.FAILURE_RULES): thesis = every point "
                       "damages by Eq. 2-25 on its own strains; yarn_crack = a broken yarn family tears "
                       "along the other family with one yarn segment's energy "
                       "(fabric_fenicsx.fem.yarn_crack; one rank, damage on); yarn_tip = the yarn crack "
                       "whose tip runs on when its yarn, read along it, reaches the segment's strength "
                       "(fabric_fenicsx.fem.yarn_tip); yarn_strain = the same for a crack's start too; "
                       "shear_lag = yarn_strain whose tip breaks when its yarn's stretch, raised by the load the "
                       "crack's broken yarns shed (Hedgepeth's shear-lag factor), reaches the segment's strength "
                       "(fabric_fenicsx.fem.shear_lag); del_zone = shear_lag whose crossings slip: the factor "
                       "at most 2, its crack cells snapping, its tip's yarn read over the uncut yarns, its "
                       "cracks' corner bridges cut "
                       "(fabric_fenicsx.fem.crack_bridges); del_zone_budget = del_zone whose snapped cells "
                       "hold alpha 1/2 and break through with one yarn segment's work per yarn they cut, in "
                       "the unit cell's energy (fabric_fenicsx.fem.crack_budget)"),
        "surrogate_cache": Key("", optional_text,
                               "directory of the surrogate's tile cache (\"\" = its default)"),
        "scatter": Key("none", choice("none", "fibrils", "weibull"),
                       "strength scatter of the yarn segments (fabric_fenicsx.material.scatter): none = "
                       "every yarn as strong as Eq. 2-25's mean; fibrils = each segment draws its own "
                       "fibrils (Eq. 2-22); weibull = Weibull-distributed critical strain per segment"),
        "seed": Key(0, integer(0), "seed of the strength scatter's field (the same on every mesh and rank)"),
        "weibull_modulus": Key(11.7, number(0.0, lo_open=True),
                               "Weibull modulus of the segment critical strain (scatter = weibull; default: "
                               "Kevlar 49 single yarns as a proxy, docs/impact_model.md)"),
        "fibrils": Key(326, integer(1), "fibrils per yarn segment (scatter = fibrils; 555 dtex / 1.7 dtex "
                       "Zylon AS)"),
    },
    "membrane": {
        "shear_modulus": Key(0.0, number(0.0, unit="N/m"),
                             "isotropic in-plane shear stiffness G of the weak-form term "
                             "fabric_fenicsx.fem.terms.IsotropicShear (0 = off: the thesis's membrane "
                             "has none, Sec. 2.1)"),
        "hourglass": Key(0.05, number(0.0, 1.0, lo_open=True),
                         "hourglass control stiffness of the reduced element as a fraction of the "
                         "straight intact yarn modulus (fabric_fenicsx.fem.terms.HourglassControl)"),
        "terms": Key([], check_term_specs,
                     "extra weak-form terms, MembraneTerm subclasses: a list of \"module:Class\" or "
                     "\"file.py:Class\" (relative to the scene file) or tables {class = \"module:Class\", "
                     "key = value} with keyword arguments (fabric_fenicsx.impact.term_specs)"),
    },
    "mesh": {
        "kind": Key("graded", choice("graded", "uniform", "aligned", "structured", "file"),
                    "graded = unstructured gmsh quadrilaterals fine at the impact point; uniform = "
                    "n x n squares; aligned = a structured grid along x and y graded like the gmsh mesh "
                    "(h_centre, h_edge, refine_radius, grading); structured = a patch of squares of side "
                    "h_centre, half-side refine_radius, turned mesh.rotation degrees from x at the impact "
                    "point, in gmsh quadrilaterals graded to h_edge; file = the quadrilaterals of mesh.file"),
        "rotation": Key(0.0, number(-360.0, 360.0, unit="deg"),
                        "angle from x of the rows of the structured patch (mesh.kind = 'structured')"),
        "file": Key("", optional_text,
                    "a gmsh .msh file of 4-node quadrilaterals covering the square [-side/2, side/2]^2 "
                    "(mesh.kind = 'file'; relative to the scene file); its edges are found by position"),
        "side": Key(0.27305, number(0.0, lo_open=True, unit="m"),
                    "side of the square fabric (10.75 in, Sec. 4.1)"),
        "h_centre": Key(2.0e-3, number(0.0, lo_open=True, unit="m"),
                        "element size within refine_radius of the impact point (graded, aligned)"),
        "h_edge": Key(8.0e-3, number(0.0, lo_open=True, unit="m"),
                      "element size far from the centre (graded, aligned)"),
        "refine_radius": Key(0.02, number(0.0, unit="m"), "radius kept at h_centre (graded, aligned)"),
        "grading": Key(0.1, number(0.0, 1.0, lo_open=True), "size growth per unit distance (graded, aligned)"),
        "n": Key(64, integer(2), "cells per side (uniform)"),
        "element": Key("reduced", choice("full", "reduced"),
                       "full = bilinear quadrilateral, yarn stresses at the Gauss points of "
                       "quadrature_degree; reduced = one point per cell with hourglass control "
                       "(membrane.hourglass), which does not lock when the yarns cross the cell edges "
                       "(docs/mesh_independence.md)"),
        "quadrature_degree": Key(2, integer(1), "quadrature degree of P1, P2 (2 = 2 x 2 Gauss points; "
                                 "element = full only)"),
    },
    "projectile": {
        "diameter": Key(0.0254, number(0.0, lo_open=True, unit="m"),
                        "diameter (not stated in the thesis; 1 in assumed)"),
        "length": Key(0.0093, number(0.0, lo_open=True, unit="m"),
                      "length (37.1 g of steel at 25.4 mm diameter)"),
        "fillet": Key(0.0, number(0.0, unit="m"), "fillet radius of the impacting edge (0, 0.8e-3, 2e-3 in Sec. 4.4.3)"),
        "mass": Key(0.0371, number(0.0, lo_open=True, unit="kg"), "mass (37.1 g, Sec. 4.1)"),
        "velocity": Key(57.3, number(0.0, lo_open=True, unit="m/s"),
                        "initial velocity, normal to the fabric at its centre (Table 4: 34.5, 39.78, "
                        "57.3, 83.06, 123.69)"),
        "x": Key(0.0, number(unit="m"), "impact point, global X (0 = centre of the fabric); the graded mesh is fine there"),
        "y": Key(0.0, number(unit="m"), "impact point, global Y (0 = centre of the fabric)"),
        "friction": Key(0.5, number(0.0, unit=""), "Coulomb friction projectile/fabric (0.5; 0.1 and 2.0 in Sec. 4.4.1)"),
        "standoff": Key(0.2e-3, number(0.0, lo_open=True, unit="m"),
                        "initial gap between the impacting face and the fabric"),
        "contact_damping": Key(1.0, number(0.0, 2.0),
                               "damping ratio of the node-on-penalty oscillator (1 = critical, "
                               "nearly plastic node impacts; fabric_fenicsx.fem.projectile)"),
        "penalty_fraction": Key(0.5, number(0.0, 0.5, lo_open=True),
                                "penalty stiffness as a fraction of its stability limit for the nodal mass and dt"),
    },
    "boundary": {
        "clamped": Key(["bottom", "top"], subset(EDGES),
                       "clamped edges: Y0/Y90 = [bottom, top] (normal to global Y), XY0/XY45 = all four"),
    },
    "run": {
        "t_end": Key(3.0e-3, number(0.0, lo_open=True, unit="s"),
                     "time limit (the run also ends on perforation or rebound, and with stop_when_held)"),
        "dt_safety": Key(0.8, number(0.0, 1.0, lo_open=True),
                         "time step = dt_safety x stable limit (smallest cell, largest wave speed)"),
        "dt_check_interval": Key(10, integer(1), "steps between re-checks of the stable time step"),
        "damping": Key(0.1, number(0.0, 1.0),
                       "stiffness-proportional damping as a fraction of critical at the highest "
                       "frequency of a membrane of unit cells (straight intact yarns, 2 w_1 x 2 w_2 cells): "
                       "the same coefficient on every mesh (docs/impact_model.md)"),
        "release_time": Key(20.0e-6, number(0.0, lo_open=True, unit="s"),
                            "time without contact after which a perforation or rebound is final"),
        "max_steps": Key(0, integer(0), "stop after this many steps (0 = no limit)"),
        "max_cells": Key(2_000_000, integer(1),
                         "refuse, before the mesh is built, a scene estimated to have more cells "
                         "(fabric_fenicsx.impact.sizing; a scene needing more memory than is free is refused too)"),
        "stop_when_held": Key(False, boolean,
                              "end the run as 'held' as soon as the fabric has brought the projectile to rest "
                              "and it turns back, without following the rebound (a ballistic limit needs only "
                              "the outcome)"),
        "energy_tolerance": Key(0.05, number(0.0, lo_open=True),
                                "a relative energy-balance error above this stops the run (damage on or off)"),
    },
    "output": {
        "xdmf_interval": Key(5.0e-5, number(0.0, unit="s"),
                             "simulated time between XDMF frames (0 = no XDMF file)"),
        "fields": Key(list(FIELDS), subset(FIELDS, allow_empty=True), "fields in the XDMF file"),
        "history_interval": Key(1.0e-6, number(0.0, lo_open=True, unit="s"),
                                "simulated time between rows of history.csv"),
        "png": Key(True, boolean, "write velocity_history.png, damage_map.png and snapshots.png at the end"),
        "animation": Key(False, boolean, "write impact.gif, the deformed fabric over the run"),
        "animation_interval": Key(5.0e-5, number(0.0, lo_open=True, unit="s"),
                                  "simulated time between the frames of impact.gif"),
        "progress_interval": Key(5.0, number(0.0, unit="s"),
                                 "wall seconds between progress lines on rank 0 (0 = none)"),
    },
}
TOP_LEVEL = {"description": "free text describing the scene"}


def describe_schema(section: str | None = None) -> str:
    """Every section and key with its default, type and meaning (for error messages and --help)."""
    lines = []
    for sec, keys in SCHEMA.items():
        if section is not None and sec != section:
            continue
        lines.append(f"[{sec}]")
        for name, key in keys.items():
            kind = getattr(key.check, "kind", "")
            lines.append(f"  {name} = {_toml_value(key.default)}   # {kind}: {key.doc}")
    return "\n".join(lines)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


# ----------------------------------------------------------------------------- scene
class Scene:
    """A validated scene: ``scene.projectile.velocity``, ``scene["run"]["t_end"]``,
    ``scene.to_dict()`` (plain dict of every section, defaults filled in)."""

    def __init__(self, data: dict[str, dict[str, Any]], source: str = "<defaults>",
                 description: str = "", given: frozenset[str] = frozenset()):
        self._data = data
        self.source = source
        self.description = description
        self.given = given
        """The keys the scene file or an override set, as "section.key"."""
        for sec, values in data.items():
            setattr(self, sec, SimpleNamespace(**values))

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self._data[section]

    def to_dict(self) -> dict[str, dict[str, Any]]:
        return copy.deepcopy(self._data)

    @property
    def name(self) -> str:
        return Path(self.source).stem if self.source != "<defaults>" else "scene"

    def __repr__(self) -> str:
        return f"Scene({self.source!r})"


def parse_override(text: str) -> tuple[str, str, Any]:
    """``"section.key=value"`` -> (section, key, value). The value is read as a TOML value
    (numbers, true/false, "strings", [lists]); a bare word that is not TOML is a string."""
    if "=" not in text:
        raise SceneError(f"--set {text!r}: expected section.key=value, e.g. projectile.velocity=57.3")
    lhs, rhs = text.split("=", 1)
    parts = lhs.strip().split(".")
    if len(parts) != 2 or not all(parts):
        raise SceneError(f"--set {text!r}: the key must be section.key, e.g. projectile.velocity; "
                         f"sections are {list(SCHEMA)}")
    rhs = rhs.strip()
    try:
        value = tomllib.loads(f"v = {rhs}")["v"]
    except tomllib.TOMLDecodeError:
        value = rhs
    return parts[0], parts[1], value


def _check_section(section: str, values: dict[str, Any], where: str) -> None:
    if section not in SCHEMA:
        raise SceneError(f"{where}: unknown section [{section}]; valid sections are {list(SCHEMA)}"
                         + (f" (and top-level keys {list(TOP_LEVEL)})" if TOP_LEVEL else ""))
    if not isinstance(values, dict):
        raise SceneError(f"{where}: [{section}] must be a table of keys, got {values!r}")
    for key in values:
        if key not in SCHEMA[section]:
            raise SceneError(f"{where}: unknown key {section}.{key}; valid keys of [{section}]:\n"
                             + describe_schema(section))


def build_scene(raw: dict[str, Any], overrides: list[str] | tuple[str, ...] = (),
                source: str = "<defaults>") -> Scene:
    """Validate a raw scene dict (as read from TOML) with ``section.key=value`` overrides
    applied on top, and fill in the defaults. Raises :class:`SceneError`."""
    description = ""
    merged: dict[str, dict[str, Any]] = {}
    for sec, values in raw.items():
        if sec in TOP_LEVEL and not isinstance(values, dict):
            if sec == "description":
                if not isinstance(values, str):
                    raise SceneError(f"{source}: description = {values!r}: must be a string")
                description = values
            continue
        _check_section(sec, values, source)
        merged.setdefault(sec, {}).update(values)
    for text in overrides:
        sec, key, value = parse_override(text)
        _check_section(sec, {key: value}, f"--set {text!r}")
        merged.setdefault(sec, {})[key] = value

    data: dict[str, dict[str, Any]] = {}
    for sec, keys in SCHEMA.items():
        data[sec] = {}
        given = merged.get(sec, {})
        for name, key in keys.items():
            value = given.get(name, copy.deepcopy(key.default))
            data[sec][name] = key.check(f"{sec}.{name}", value)
    _cross_check(data)
    if data["mesh"]["element"] == "reduced" and "quadrature_degree" in merged.get("mesh", {}):
        raise SceneError(f"{source}: mesh.quadrature_degree applies to mesh.element = 'full' only; "
                         "the reduced element has one point per cell (set mesh.element = 'full' to "
                         "choose the Gauss rule)")
    given = frozenset(f"{sec}.{key}" for sec, values in merged.items() for key in values)
    return Scene(data, source, description, given)


def _cross_check(d: dict[str, dict[str, Any]]) -> None:
    m, p = d["mesh"], d["projectile"]
    if m["kind"] == "file" and not m["file"]:
        raise SceneError("mesh.kind = 'file' needs mesh.file: a gmsh .msh file of quadrilaterals")
    if m["kind"] in ("graded", "aligned", "structured"):
        if m["h_centre"] > m["h_edge"]:
            raise SceneError(f"mesh.h_centre = {m['h_centre']!r}: must not exceed mesh.h_edge = {m['h_edge']!r}")
        if m["h_edge"] > m["side"] / 2:
            raise SceneError(f"mesh.h_edge = {m['h_edge']!r}: must be <= mesh.side / 2 = {m['side'] / 2!r}")
    if m["kind"] == "structured":
        from fabric_fenicsx.fem.structured_patch import largest_patch_radius, patch_half_side

        half = patch_half_side(m["refine_radius"], m["h_centre"])
        room = largest_patch_radius(m["side"], (p["x"], p["y"]), m["rotation"], m["h_centre"])
        if half > room:
            raise SceneError(f"mesh.refine_radius = {m['refine_radius']!r}: the structured patch (half-side "
                             f"{half:.6g} m, turned {m['rotation']:g} degrees) must keep mesh.h_centre from every "
                             f"edge of the fabric; at most {room:.6g} m here")
    limit = min(p["diameter"], p["length"]) / 2
    if p["fillet"] > limit:
        raise SceneError(f"projectile.fillet = {p['fillet']!r}: must be <= min(diameter, length) / 2 = {limit!r}")
    if p["diameter"] >= m["side"]:
        raise SceneError(f"projectile.diameter = {p['diameter']!r}: must be smaller than mesh.side = {m['side']!r}")
    reach = m["side"] / 2 - p["diameter"] / 2
    for axis in ("x", "y"):
        if abs(p[axis]) >= reach:
            raise SceneError(f"projectile.{axis} = {p[axis]!r}: the projectile's face must lie inside the "
                             f"fabric, |{axis}| < mesh.side / 2 - diameter / 2 = {reach!r}")


def yarns_follow_the_mesh(scene: Scene) -> bool:
    """Whether every cell edge of the scene's mesh runs along a yarn: a structured mesh
    (``uniform`` or ``aligned``, edges along x and y) with the warp at a multiple of 90 degrees."""
    angle = scene.material.angle % 90.0
    return scene.mesh.kind in ("uniform", "aligned") and min(angle, 90.0 - angle) < 1e-9


GRADED_KEYS = ("h_centre", "h_edge", "refine_radius", "grading")
"""Mesh keys of the graded and aligned meshes; the uniform mesh uses ``mesh.n`` alone."""


def ignored_keys_warning(scene: Scene) -> str:
    """The warning for mesh keys the scene gives but its mesh does not use ("" for none)."""
    kind = scene.mesh.kind
    for key, owner in (("rotation", "structured"), ("file", "file")):
        if f"mesh.{key}" in scene.given and kind != owner:
            return f"mesh.{key} is ignored: it applies to mesh.kind = {owner!r}, not {kind!r}"
    if kind == "file":
        unused = [f"mesh.{k}" for k in (*GRADED_KEYS, "n") if f"mesh.{k}" in scene.given]
        if unused:
            return (f"{', '.join(unused)} {'is' if len(unused) == 1 else 'are'} ignored: mesh.kind = "
                    "'file' takes its cells from mesh.file")
    elif kind == "uniform":
        unused = [f"mesh.{k}" for k in GRADED_KEYS if f"mesh.{k}" in scene.given]
        if unused:
            return (f"{', '.join(unused)} {'is' if len(unused) == 1 else 'are'} ignored: mesh.kind = "
                    f"'uniform' is {scene.mesh.n} x {scene.mesh.n} squares (mesh.n); the sizes apply to "
                    "mesh.kind = 'graded' or 'aligned'")
    elif "mesh.n" in scene.given:
        return (f"mesh.n is ignored: mesh.kind = {scene.mesh.kind!r} takes its sizes from mesh.h_centre "
                "and mesh.h_edge; mesh.n applies to mesh.kind = 'uniform'")
    return ""


def locking_warning(scene: Scene) -> str:
    """The warning the impact command prints for a locking-prone combination ("" for none):
    the fully integrated element on a mesh whose cell edges do not follow the yarns, where it
    shows spurious yarn strain of first order in h (intra-ply shear locking,
    tests/fem/test_hourglass.py) and starts damage too early."""
    if scene.mesh.element != "full" or yarns_follow_the_mesh(scene):
        return ""
    where = ("the unstructured graded mesh" if scene.mesh.kind == "graded"
             else f"a mesh along x and y with the warp at {scene.material.angle:g} degrees")
    return (f"mesh.element = 'full' on {where}: the yarns cross the cell edges and the fully "
            "integrated element locks in intra-ply shear (spurious yarn strain, damage too early); "
            "use mesh.element = 'reduced' (see docs/mesh_independence.md)")


def load_scene(path: str | Path | None, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    """Read and validate a scene TOML file (``None``: defaults only) with overrides, and the
    fabric file it names (``fabric.file``, relative to the scene file's folder, or to the
    working folder without a scene file), which is read and validated too, and the term
    classes of ``membrane.terms`` (imported, their arguments checked; files made absolute)."""
    if path is None:
        scene, base = build_scene({}, overrides), Path.cwd()
    else:
        path = Path(path)
        scene, base = build_scene(_read_toml(path), overrides, str(path)), path.parent
    _resolve_fabric_file(scene, base)
    _resolve_mesh_file(scene, base)
    if scene["membrane"]["terms"]:
        scene["membrane"]["terms"] = resolve_term_specs(scene["membrane"]["terms"], base)
        scene.membrane.terms = scene["membrane"]["terms"]
    return scene


def _read_toml(path: Path) -> dict[str, Any]:
    """The scene file's TOML, or a :class:`SceneError` saying why it cannot be read."""
    where = f"scene file {str(path)!r}"
    if path.is_dir():
        raise SceneError(f"{where} is a folder; give a scene TOML file, e.g. demos/scenes/y90.toml")
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise SceneError(f"{where} not found") from None
    except OSError as err:
        raise SceneError(f"{where} cannot be read: {err.strerror or err}") from None
    except UnicodeDecodeError as err:
        raise SceneError(f"{where} is not UTF-8 text (byte {err.object[err.start]:#04x} at offset "
                         f"{err.start}); save it as UTF-8") from None
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"{where} is not valid TOML: {err}") from None


def _regular_file(key: str, given: str, base: Path, hint: str) -> Path:
    """The file a scene key names, absolute (relative to ``base``), or a :class:`SceneError`
    saying what is there instead and ``hint``."""
    f = Path(given)
    if not f.is_absolute():
        f = base / f
    if not f.is_file():
        what = ("a folder, not a file" if f.is_dir() else
                "not a regular file (a device, a pipe or a socket)" if f.exists() else "no such file")
        raise SceneError(f"{key} = {given!r}: {what} ({f}); {hint}")
    return f


def _resolve_fabric_file(scene: Scene, base: Path) -> None:
    """Make ``fabric.file`` absolute (relative to ``base``) and check that it reads as a fabric."""
    given = scene["fabric"]["file"]
    if not given:
        return
    f = _regular_file("fabric.file", given, base, "give a fabric TOML file (fabric_fenicsx.material.fabric."
                      "Fabric.load) or \"\" for the built-in fabric.name")
    scene["fabric"]["file"] = str(f)
    scene.fabric.file = str(f)
    load_fabric(scene)


def _resolve_mesh_file(scene: Scene, base: Path) -> None:
    """Make ``mesh.file`` absolute (relative to ``base``) and check that it is a gmsh file of
    quadrilaterals covering the scene's square (:func:`~fabric_fenicsx.fem.mesh_file.square_msh_problem`)."""
    given = scene["mesh"]["file"]
    if not given or scene.mesh.kind != "file":
        return
    f = _regular_file("mesh.file", given, base, "give a gmsh .msh file of quadrilaterals")
    from fabric_fenicsx.fem.mesh_file import square_msh_problem

    try:
        problem = square_msh_problem(f, scene.mesh.side)
    except Exception as err:   # gmsh's own words for a file it cannot read
        problem = f"gmsh cannot read it: {type(err).__name__}: {err}"
    if problem:
        raise SceneError(f"mesh.file = {given!r}: {problem}")
    scene["mesh"]["file"] = str(f)
    scene.mesh.file = str(f)


def load_fabric(scene: Scene):
    """The fabric of ``fabric.file`` (a :class:`~fabric_fenicsx.material.fabric.Fabric`), or a
    :class:`SceneError` naming ``fabric.file`` and what is valid."""
    from fabric_fenicsx.material.fabric import Fabric

    given = scene["fabric"]["file"]
    try:
        return Fabric.load(given)
    except OSError as err:
        raise SceneError(f"fabric.file = {given!r}: cannot be read: {err.strerror or err}") from None
    except ValueError as err:
        reason = str(err).removeprefix(f"{given}: ")  # Fabric.load names the file first
        raise SceneError(f"fabric.file = {given!r}: {reason}") from None


def check_output_dir(path: str | Path) -> Path:
    """The output folder, created if missing and shown to be writable, or an :class:`InputError`
    naming it and saying why it cannot be used (checked before any work)."""
    p = Path(path)
    where = f"output folder (--out) {str(p)!r}"
    if p.exists() and not p.is_dir():
        raise InputError(f"{where} is an existing file; give a folder (it is created if missing)")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{where} cannot be created: {err.strerror or err}; give a folder in a "
                         "writable place") from None
    try:
        with tempfile.TemporaryFile(dir=p, prefix=".write-test-"):
            pass
    except OSError as err:
        raise InputError(f"{where} is not writable: {err.strerror or err}; give a writable folder") from None
    return p
