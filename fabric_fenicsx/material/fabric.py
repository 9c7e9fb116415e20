"""Yarn and fabric parameters (SI units: N, m, kg).

A fabric is two yarn families, warp (i = 1) and fill (i = 2), each described by the
half-segment of the unit cell (thesis section 2.2.2, Figure 2-5): its length L_i, its
reference angle Phi_i(L_i) at the membrane surface (BC2), its stretch stiffness A_i^0,
bending stiffness B_i^0 and critical stretch mu_i^crit. The reference shape is
Phi_i(S) = Phi_i(L_i) sin(pi S / (2 L_i))  (Eq. 3-5).

Derived quantities follow from that shape: the projected half-length
w_i = int_0^L cos Phi_i dS, the reference height H_i = int_0^L sin Phi_i dS and the crimp
L_i / w_i - 1.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fabric_fenicsx.material.fibril import ExponentialDamage, damage_law_from_dict

METRE_PER_INCH = 0.0254

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(64)


def _check_positive(owner: str, name: str, value: float) -> None:
    if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value > 0):
        raise ValueError(f"{owner}.{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class Yarn:
    """One yarn family of the unit cell (Table 1 of the thesis).

    Attributes
    ----------
    L : half-segment length L_i of the unit cell (m).
    Phi_L : reference angle Phi_i(L_i) at BC2 (rad), in [0, pi/2).
    A0 : undamaged stretch stiffness A_i^0 (N).
    B0 : undamaged bending stiffness B_i^0 (N m^2).
    mu_crit : critical stretch mu_i^crit (> 1) at which damage starts (Eq. 2-25).
    name : "warp" or "fill" (used in messages only).
    """

    L: float
    Phi_L: float
    A0: float
    B0: float
    mu_crit: float
    name: str = "yarn"

    def __post_init__(self) -> None:
        owner = f"Yarn({self.name})"
        for attr in ("L", "A0", "B0"):
            _check_positive(owner, attr, getattr(self, attr))
        phi = self.Phi_L
        if not (isinstance(phi, (int, float, np.floating)) and math.isfinite(phi)
                and 0.0 <= phi < math.pi / 2):
            raise ValueError(f"{owner}.Phi_L must lie in [0, pi/2), got {phi!r}")
        mu = self.mu_crit
        if not (isinstance(mu, (int, float, np.floating)) and math.isfinite(mu) and mu > 1.0):
            raise ValueError(f"{owner}.mu_crit must be a finite number > 1, got {mu!r}")

    def Phi(self, S):
        """Reference yarn angle Phi_i(S) = Phi_i(L_i) sin(pi S / 2 L_i) (Eq. 3-5)."""
        return self.Phi_L * np.sin(0.5 * np.pi * np.asarray(S) / self.L)

    def dPhi(self, S):
        """Reference curvature dPhi_i/dS of Eq. 3-5."""
        k = 0.5 * np.pi / self.L
        return self.Phi_L * k * np.cos(k * np.asarray(S))

    def _integral(self, f) -> float:
        S = 0.5 * self.L * (_GAUSS_X + 1.0)
        return float(0.5 * self.L * np.sum(_GAUSS_W * f(self.Phi(S))))

    @property
    def w(self) -> float:
        """Projected half-length w_i = int_0^L cos Phi_i dS (m); 2 w_i is the yarn spacing."""
        return self._integral(np.cos)

    @property
    def H(self) -> float:
        """Reference height of the crimped half-yarn, int_0^L sin Phi_i dS (m)."""
        return self._integral(np.sin)

    @property
    def crimp(self) -> float:
        """Degree of crimp L_i / w_i - 1 (dimensionless)."""
        return self.L / self.w - 1.0

    def scaled(self, **changes) -> "Yarn":
        """A copy with some fields replaced (e.g. ``yarn.scaled(B0=...)``)."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class Fabric:
    """A plain-woven fabric: warp (yarn 1), fill (yarn 2), cross-section and density.

    Attributes
    ----------
    warp, fill : the two yarn families.
    area : yarn cross-section area C (m^2).
    density : yarn volume density rho (kg/m^3).
    damage : fibril-scale damage law alpha(mu, mu_crit) shared by both yarns (Eq. 2-25 by default).
    yarns_per_metre : nominal yarn count of the weave (informative; the model uses 1/(2 w_i)).
    name : label used in output.
    """

    warp: Yarn
    fill: Yarn
    area: float
    density: float
    damage: object = field(default_factory=ExponentialDamage)
    yarns_per_metre: float | None = None
    name: str = "fabric"

    def __post_init__(self) -> None:
        _check_positive("Fabric", "area", self.area)
        _check_positive("Fabric", "density", self.density)
        if self.yarns_per_metre is not None:
            _check_positive("Fabric", "yarns_per_metre", self.yarns_per_metre)
        for attr in ("warp", "fill"):
            if not isinstance(getattr(self, attr), Yarn):
                raise ValueError(f"Fabric.{attr} must be a Yarn, got {getattr(self, attr)!r}")
        if not hasattr(self.damage, "alpha"):
            raise ValueError(f"Fabric.damage must be a damage law with alpha(mu, mu_crit), got {self.damage!r}")

    @property
    def yarns(self) -> tuple[Yarn, Yarn]:
        return (self.warp, self.fill)

    @property
    def areal_density(self) -> float:
        """Mass per reference area rho C (2 L_1 + 2 L_2) / (4 w_1 w_2) (kg/m^2)."""
        return (self.density * self.area * 2.0 * (self.warp.L + self.fill.L)
                / (4.0 * self.warp.w * self.fill.w))

    def replace(self, **changes) -> "Fabric":
        return dataclasses.replace(self, **changes)

    def with_yarn(self, which: str, **changes) -> "Fabric":
        """A copy whose ``which`` ("warp" or "fill") yarn has some fields replaced."""
        if which not in ("warp", "fill"):
            raise ValueError(f"which must be 'warp' or 'fill', got {which!r}")
        return self.replace(**{which: getattr(self, which).scaled(**changes)})

    def to_dict(self) -> dict:
        def yarn_dict(y: Yarn) -> dict:
            return {"L": y.L, "Phi_L": y.Phi_L, "A0": y.A0, "B0": y.B0, "mu_crit": y.mu_crit}

        d = {"name": self.name, "area": self.area, "density": self.density,
             "warp": yarn_dict(self.warp), "fill": yarn_dict(self.fill),
             "damage": self.damage.to_dict()}
        if self.yarns_per_metre is not None:
            d["yarns_per_metre"] = self.yarns_per_metre
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "Fabric":
        """A fabric from a dict of :meth:`to_dict`'s keys (SI units). Every key is checked
        before anything is built: a ValueError names the key as written in a fabric file
        (``area``, ``[warp] A0``, ``[damage] law``) and says what is valid."""
        _check_fabric_keys(d)
        yarns = {name: _yarn_from_dict(name, d[name]) for name in ("warp", "fill")}
        numbers = {key: _file_number(key, d[key], unit) for key, unit in _FABRIC_NUMBERS.items() if key in d}
        try:
            damage = damage_law_from_dict(d["damage"]) if "damage" in d else ExponentialDamage()
        except (TypeError, ValueError) as err:
            raise ValueError(f"[damage] {err}") from None
        return cls(warp=yarns["warp"], fill=yarns["fill"], area=numbers["area"],
                   density=numbers["density"], damage=damage,
                   yarns_per_metre=numbers.get("yarns_per_metre"), name=str(d.get("name", "fabric")))

    @classmethod
    def load(cls, path: str | Path) -> "Fabric":
        """Read a fabric from a TOML file (keys as in :meth:`to_dict`, SI units). A file that is
        not UTF-8 TOML or not a valid fabric raises ValueError starting with the file's path;
        a file that cannot be opened raises OSError."""
        with open(path, "rb") as f:
            raw = f.read()
        try:
            data = tomllib.loads(raw.decode("utf-8"))
        except UnicodeDecodeError as err:
            raise ValueError(f"{path}: not UTF-8 text (byte {raw[err.start]:#04x} at offset {err.start})") from None
        except tomllib.TOMLDecodeError as err:
            raise ValueError(f"{path}: not valid TOML: {err}") from None
        try:
            return cls.from_dict(data)
        except ValueError as err:
            raise ValueError(f"{path}: {err}") from None

    def save(self, path: str | Path) -> None:
        """Write the fabric as TOML (SI units), readable by :meth:`load`."""
        Path(path).write_text(_to_toml(self.to_dict()))

    def describe(self) -> str:
        lines = [f"{self.name}: areal density {self.areal_density:.4f} kg/m^2"]
        for y in self.yarns:
            lines.append(f"  {y.name}: L = {y.L*1e3:.4f} mm, w = {y.w*1e3:.4f} mm, "
                         f"crimp = {100*y.crimp:.2f} %, H = {y.H*1e6:.2f} um, A0 = {y.A0:.0f} N, "
                         f"B0 = {y.B0*1e6:.4f} N mm^2, mu_crit = {y.mu_crit}")
        return "\n".join(lines)


# ----------------------------------------------------------------------------- reading files
_YARN_KEYS = {
    "L": ("half-segment length", "m", "> 0", lambda v: v > 0),
    "Phi_L": ("reference angle", "rad", "in [0, pi/2)", lambda v: 0 <= v < math.pi / 2),
    "A0": ("stretch stiffness", "N", "> 0", lambda v: v > 0),
    "B0": ("bending stiffness", "N m^2", "> 0", lambda v: v > 0),
    "mu_crit": ("critical stretch", "", "> 1", lambda v: v > 1),
}
"""Keys of a ``[warp]`` / ``[fill]`` table: meaning, unit, what is valid and its test."""
_FABRIC_NUMBERS = {"area": "m^2", "density": "kg/m^3", "yarns_per_metre": "1/m"}
_FABRIC_KEYS = ("name", "area", "density", "warp", "fill", "damage", "yarns_per_metre")
_REQUIRED = ("area", "density", "warp", "fill")
_FILE_LAYOUT = ("area (m^2) and density (kg/m^3), tables [warp] and [fill] with L (m), Phi_L (rad), "
                "A0 (N), B0 (N m^2), mu_crit; optional: name, yarns_per_metre (1/m), [damage] with law = "
                "\"exponential\" (beta, width) or \"bundle\" (d0_over_h0, n, seed)")


def _check_fabric_keys(d) -> None:
    """Unknown or missing top-level keys of a fabric description, as a ValueError."""
    if not isinstance(d, dict):
        raise ValueError(f"a fabric description must be a table of keys, got {d!r}")
    unknown = sorted(set(d) - set(_FABRIC_KEYS))
    if unknown:
        raise ValueError(f"unknown key(s) {unknown}; a fabric file has {_FILE_LAYOUT}")
    missing = [k for k in _REQUIRED if k not in d]
    if missing:
        raise ValueError(f"missing key(s) {missing}; a fabric file has {_FILE_LAYOUT}")


def _file_number(key: str, value, unit: str) -> float:
    """A positive finite number of a fabric file, or a ValueError naming the key."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{key} = {value!r}: must be a number ({unit})")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{key} = {value!r}: must be a positive finite number ({unit})")
    return float(value)


def _yarn_from_dict(name: str, y) -> Yarn:
    """The ``[warp]`` or ``[fill]`` table of a fabric file as a :class:`Yarn`, every key checked."""
    if not isinstance(y, dict):
        raise ValueError(f"{name} must be a table [{name}] with {sorted(_YARN_KEYS)}, got {y!r}")
    if set(y) != set(_YARN_KEYS):
        missing, unknown = sorted(set(_YARN_KEYS) - set(y)), sorted(set(y) - set(_YARN_KEYS))
        raise ValueError(f"[{name}] needs exactly the keys {sorted(_YARN_KEYS)}"
                         + (f"; missing {missing}" if missing else "") + (f"; unknown {unknown}" if unknown else ""))
    values = {}
    for key, (meaning, unit, valid, ok) in _YARN_KEYS.items():
        v = y[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not ok(v):
            raise ValueError(f"[{name}] {key} = {v!r}: must be a finite number {valid} "
                             f"({meaning}{', ' + unit if unit else ''})")
        values[key] = float(v)
    return Yarn(name=name, **values)

def _to_toml(d: dict) -> str:
    """Minimal TOML writer for a two-level dict of numbers and strings."""

    def value(v) -> str:
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(v, bool):
            return "true" if v else "false"
        return repr(float(v)) if isinstance(v, float) else repr(v)

    top = [f"{k} = {value(v)}" for k, v in d.items() if not isinstance(v, dict)]
    tables = [f"\n[{k}]\n" + "\n".join(f"{kk} = {value(vv)}" for kk, vv in v.items())
              for k, v in d.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n" + "\n".join(tables) + "\n"


def zylon_as(bending: str = "max") -> Fabric:
    """500 denier PBO Zylon AS plain weave, 35 x 35 yarns per inch (Table 1 of the thesis).

    ``bending`` selects the bending stiffness bound of both yarns: "max" (the thesis's
    default for the static scenes) or "min" (one fifth of it, section 3.2).
    """
    if bending not in ("max", "min"):
        raise ValueError(f"bending must be 'max' or 'min', got {bending!r}")
    n_mm2 = 1e-6  # N mm^2 -> N m^2
    b_warp, b_fill = (0.2657, 0.2935) if bending == "max" else (0.0531, 0.0587)
    warp = Yarn(L=0.3741e-3, Phi_L=0.3481, A0=4338.0, B0=b_warp * n_mm2, mu_crit=1.025, name="warp")
    fill = Yarn(L=0.3650e-3, Phi_L=0.1546, A0=4724.0, B0=b_fill * n_mm2, mu_crit=1.0297, name="fill")
    return Fabric(warp=warp, fill=fill, area=3.61e-8, density=1560.0,
                  damage=ExponentialDamage(beta=124.0, width=0.03),
                  yarns_per_metre=35.0 / METRE_PER_INCH, name=f"Zylon AS (B {bending})")
