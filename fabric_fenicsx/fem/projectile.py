"""Rigid flat-ended cylindrical projectile and its penalty contact with the fabric nodes.

Thesis, Chapter 4, Section 4.1: "a flat-ended cylindrical steel projectile of 37.1 g" hits a
square PBO Zylon fabric "at its center", the projectile is "an analytical rigid body", and the
projectile-fabric friction is 0.5 (Rebouillat [34]); Section 4.4.1 also uses 0.1 and 2.0 and
Section 4.4.3 fillets the impacting edge by 0.8 mm and 2 mm. ABAQUS used kinematic contact; an
explicit FE code without constraint enforcement uses a node-to-rigid-surface penalty instead.

Geometry and conventions (SI units):

* The fabric lies in the plane z = 0 initially; the projectile axis is parallel to z through
  ``axis_xy`` and the projectile moves towards -z. Its *position* is the height ``z`` of its
  impacting face; the solid occupies z_face <= z <= z_face + length.
* The impacting edge may carry a fillet of radius ``fillet`` (0 = sharp edge). The back edge
  stays sharp; no fabric reaches it.
* The contact gap of a node is the signed distance to the solid (negative inside), evaluated
  with the rounded-box distance in the (radius, height) half-plane (I. Quilez, "sdRoundBox"
  with a per-corner radius), which covers the face, the fillet and the side in one vectorised
  formula. The outward normal is its analytic gradient.

Contact law (per penetrating node, penetration p = -g > 0, rate pdot = -n . v_rel):

* normal force  f_n = max(k p + c pdot, 0) n,  c = 2 zeta sqrt(k m_node);
* Coulomb friction f_t = -min(mu f_n, m_node |v_t| / dt) v_t / |v_t|, opposing the sliding
  velocity v_t of the node relative to the projectile surface (the projectile translates along
  z only);
* action = reaction: the projectile receives f_projectile = -sum(f_nodes).

Time integration follows the fabric's central-difference scheme: contact forces at step n are
evaluated with the positions x^n, z^n and the half-step velocities v^(n-1/2), vz^(n-1/2).

This module is pure numpy and works on the nodes a rank owns. Under MPI each rank passes only
its owned nodes (not ghosts, or the reaction is counted twice) and the driver sums
``f_projectile`` and the energies in ``info`` over ranks before calling :func:`advance`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from fabric_fenicsx.fem.contact_kernel import penalty_forces

__all__ = [
    "Projectile",
    "PenaltyContact",
    "ProjectileState",
    "advance",
    "contact_work",
    "critical_omega_dt",
    "stable_penalty",
]

# Largest usable fraction of the central-difference limit for a *one-sided* penalty spring:
# entering and leaving contact inside a step is a discontinuity, and a node dropped on the face
# came back with up to 1.55x its kinetic energy (undamped) at 0.6 and 2.4x at 0.8.
_MAX_PENALTY_FRACTION = 0.5

# A node deeper than this fraction of min(radius, length/2) is pushed out of the wrong surface
# by a signed-distance contact, so the contact has broken down.
_MAX_PENETRATION_FRACTION = 0.25


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return value


def _positive(name: str, value: float) -> float:
    value = _finite(name, value)
    if value <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return value


@njit(cache=True, nogil=True)
def _all_finite(a):
    """numpy.isfinite(a).all() (compiled: the contact checks its points at every step)."""
    for value in a.flat:
        if not math.isfinite(value):
            return False
    return True


@njit(cache=True, nogil=True)
def _all_finite_positive(a):
    """(numpy.isfinite(a) & (a > 0.0)).all() (compiled, as :func:`_all_finite`)."""
    for value in a.flat:
        if not (math.isfinite(value) and value > 0.0):
            return False
    return True


def _points(name: str, x: Any) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {arr.shape}")
    if not _all_finite(arr):
        bad = int(np.flatnonzero(~np.all(np.isfinite(arr), axis=1))[0])
        raise ValueError(f"{name} has non-finite entries, first at row {bad}: {arr[bad]}")
    return arr


def _per_node(name: str, value: Any, n: int) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != n):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got {arr.shape}")
    if arr.ndim == 0:
        arr = np.broadcast_to(arr, (n,))
    if not _all_finite_positive(arr):
        bad = int(np.flatnonzero(~(np.isfinite(arr) & (arr > 0.0)))[0])
        raise ValueError(f"{name} must be finite and > 0, got {arr[bad]!r} at node {bad}")
    return arr


@njit(cache=True, nogil=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
def _gap_and_normal_at(x, y, z, z_face, R, half, fillet, ax, ay):
    """:meth:`Projectile.gap_and_normal` of the point (x, y, z): (gap, n_x, n_y, n_z) (only
    compiled code calls it: no Python entry point to compile)."""
    dx, dy = x - ax, y - ay
    r = math.hypot(dx, dy)
    hm = z - z_face - half  # height above the mid-plane of the solid
    front = hm < 0.0
    rr = fillet if front else 0.0  # only the impacting edge is filleted
    qx = r - R + rr
    qy = abs(hm) - half + rr
    mx, my = max(qx, 0.0), max(qy, 0.0)
    mlen = math.hypot(mx, my)
    if mlen > 0.0:  # outside
        gap = mlen - rr
        gx, gy = mx / mlen, my / mlen
    else:
        gap = max(qx, qy) - rr
        # inside: nearer the side than the face; ties (to round-off) go to the face
        side_in = qx > qy + 1e-12 * (R + half)
        gx, gy = (1.0, 0.0) if side_in else (0.0, 1.0)
    er_x, er_y = (1.0, 0.0) if r == 0.0 else (dx / r, dy / r)
    return gap, gx * er_x, gx * er_y, (-gy if front else gy)


@njit(cache=True, nogil=True)
def _gap_and_normal(x, z_face, R, half, fillet, ax, ay, gap, normal):
    """:meth:`Projectile.gap_and_normal` per point (compiled: it runs at every step)."""
    for p in range(x.shape[0]):
        gap[p], normal[p, 0], normal[p, 1], normal[p, 2] = _gap_and_normal_at(
            x[p, 0], x[p, 1], x[p, 2], z_face, R, half, fillet, ax, ay)


@njit(cache=True, nogil=True)
def _inside(x, z_face, length, R, half, fillet, ax, ay, r2, idx, pen, normal):
    """The points of ``x`` inside the solid in one pass, as ``PenaltyContact.forces`` found them
    by numpy selections: those inside the bounding cylinder (:func:`_in_cylinder`, bounds z_face
    and z_face + length) whose gap (:func:`_gap_and_normal_at`) is < 0, in order, their indices
    into ``idx``, penetrations -gap into ``pen`` and normals into ``normal`` (rows). Returns
    their number and the largest penetration (-inf if none)."""
    m = 0
    deepest = -math.inf
    z_hi = z_face + length
    for p in range(x.shape[0]):
        dx, dy, z = x[p, 0] - ax, x[p, 1] - ay, x[p, 2]
        if not ((z > z_face) & (z < z_hi) & (dx * dx + dy * dy < r2)):
            continue
        gap, n0, n1, n2 = _gap_and_normal_at(x[p, 0], x[p, 1], z, z_face, R, half, fillet, ax, ay)
        if gap < 0.0:
            idx[m], pen[m] = p, -gap
            normal[m, 0], normal[m, 1], normal[m, 2] = n0, n1, n2
            deepest = max(deepest, -gap)
            m += 1
    return m, deepest


@njit(cache=True, nogil=True)
def _in_cylinder(x, z_lo, z_hi, ax, ay, r2, inside):
    """:meth:`Projectile.candidates` per point (compiled: it runs at every step): z_lo < z <
    z_hi and (x - ax)^2 + (y - ay)^2 < r2, the same operations as the array expression."""
    for p in range(x.shape[0]):
        dx, dy, z = x[p, 0] - ax, x[p, 1] - ay, x[p, 2]
        inside[p] = (z > z_lo) & (z < z_hi) & (dx * dx + dy * dy < r2)


@dataclass(frozen=True)
class Projectile:
    """Rigid flat-ended cylinder with an optionally filleted impacting edge (thesis Sec. 4.1).

    diameter, length, fillet in m; mass in kg; velocity in m/s, positive = moving towards -z
    (into the fabric); friction = Coulomb coefficient projectile/fabric; axis_xy = (x, y) of the
    axis; z0 = initial height of the impacting face (a small stand-off above the fabric).
    The default length makes a 37.1 g steel disc of 25.4 mm diameter
    (0.0371 / (7850 * pi * 0.0127**2) = 9.3 mm).
    """

    diameter: float = 0.0254
    length: float = 0.0093
    fillet: float = 0.0
    mass: float = 0.0371
    velocity: float = 57.3
    friction: float = 0.5
    axis_xy: tuple[float, float] = (0.0, 0.0)
    z0: float = 0.5e-3

    def __post_init__(self) -> None:
        _positive("diameter", self.diameter)
        _positive("length", self.length)
        _positive("mass", self.mass)
        _finite("velocity", self.velocity)
        _finite("z0", self.z0)
        fillet = _finite("fillet", self.fillet)
        limit = min(0.5 * self.diameter, 0.5 * self.length)
        if not 0.0 <= fillet <= limit:
            raise ValueError(
                f"fillet must be in [0, min(diameter/2, length/2)] = [0, {limit}], got {fillet!r}"
            )
        if _finite("friction", self.friction) < 0.0:
            raise ValueError(f"friction must be >= 0, got {self.friction!r}")
        try:
            axis = tuple(float(a) for a in self.axis_xy)
        except TypeError as exc:
            raise ValueError(f"axis_xy must be a pair (x, y), got {self.axis_xy!r}") from exc
        if len(axis) != 2 or not all(math.isfinite(a) for a in axis):
            raise ValueError(f"axis_xy must be a finite pair (x, y), got {self.axis_xy!r}")
        object.__setattr__(self, "axis_xy", axis)

    @property
    def radius(self) -> float:
        return 0.5 * self.diameter

    def _z_face(self, z_face: float | None) -> float:
        return self.z0 if z_face is None else _finite("z_face", z_face)

    def gap_and_normal(
        self, x: Any, z_face: float | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance g (n,) of the points x (n, 3) to the projectile and its outward
        unit normal (n, 3), the gradient of g. g < 0 inside the solid.

        z_face is the current height of the impacting face (default: z0).

        Where the distance is not differentiable (the sharp corner for fillet = 0, points
        equidistant from face and side inside the solid) the normal of the face is taken when
        the point is no deeper below the face than inside the side, else the side's radial
        normal; on the axis the radial direction is taken as +x.
        """
        return self._distance(_points("x", x), z_face)

    def _distance(self, x: np.ndarray, z_face: float | None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`gap_and_normal` of points ``x`` already checked (shape (n, 3), finite)."""
        x = np.ascontiguousarray(x)
        gap, normal = np.empty(x.shape[0]), np.empty(x.shape)
        _gap_and_normal(x, self._z_face(z_face), self.radius, 0.5 * self.length, self.fillet,
                        self.axis_xy[0], self.axis_xy[1], gap, normal)
        return gap, normal

    def candidates(self, x: np.ndarray, z_face: float | None = None) -> np.ndarray:
        """Boolean mask of the points inside the bounding cylinder of the solid: the only ones
        that can have g < 0."""
        zf = self._z_face(z_face)
        x = np.asarray(x, dtype=float)
        inside = np.empty(x.shape[0], dtype=bool)
        _in_cylinder(x, zf, zf + self.length, self.axis_xy[0], self.axis_xy[1], self.radius**2, inside)
        return inside

    def may_touch(
        self, fabric_z_max: float, z_face: float | None = None, margin: float = 0.0
    ) -> bool:
        """Cheap test before any contact search: can the face (at z_face, default z0) touch a
        fabric whose highest node is at fabric_z_max? Pass margin >= |vz| dt to look one step
        ahead. Stays True after perforation, when the fabric still rubs on the side."""
        zf = self._z_face(z_face)
        margin = _finite("margin", margin)
        if margin < 0.0:
            raise ValueError(f"margin must be >= 0, got {margin!r}")
        return bool(zf <= _finite("fabric_z_max", fabric_z_max) + margin)


@dataclass(frozen=True)
class ProjectileState:
    """Rigid-body state in the central-difference scheme: face height z = z^n (m) and the
    half-step velocity vz = vz^(n-1/2) (m/s, z component, negative when moving into the
    fabric), with the mass (kg) so that :func:`advance` needs nothing else."""

    z: float
    vz: float
    mass: float

    def __post_init__(self) -> None:
        _finite("z", self.z)
        _finite("vz", self.vz)
        _positive("mass", self.mass)

    @classmethod
    def initial(cls, projectile: Projectile) -> "ProjectileState":
        """Start at z0 with vz = -velocity. The projectile starts in free flight (no force), so
        vz^(-1/2) = vz^0."""
        return cls(z=projectile.z0, vz=-projectile.velocity, mass=projectile.mass)

    @property
    def kinetic_energy(self) -> float:
        return 0.5 * self.mass * self.vz**2


def advance(state: ProjectileState, f_z_total: float, dt: float) -> ProjectileState:
    """One central-difference step of the rigid projectile along z:
    vz^(n+1/2) = vz^(n-1/2) + dt f_z^n / M,  z^(n+1) = z^n + dt vz^(n+1/2).

    f_z_total is the z component of the contact force on the projectile summed over all MPI
    ranks (``f_projectile[2]`` of :meth:`PenaltyContact.forces`, reduced). Lateral forces and
    torques are not applied: the projectile translates along its axis only.
    """
    f = _finite("f_z_total", f_z_total)
    dt = _positive("dt", dt)
    vz = state.vz + dt * f / state.mass
    return ProjectileState(z=state.z + dt * vz, vz=vz, mass=state.mass)


def contact_work(
    f_nodes: Any,
    v_old: Any,
    v_new: Any,
    f_projectile: Any,
    vz_old: float,
    vz_new: float,
    dt: float,
) -> float:
    """Work done in one central-difference step by the contact pair on the nodes and the
    projectile: dt [sum f . (v^(n-1/2) + v^(n+1/2)) / 2 + f_p,z (vz^(n-1/2) + vz^(n+1/2)) / 2].

    This is exactly the change of the half-step kinetic energy the contact forces cause, so
    with it the discrete energy balance closes to round-off. Since f_p = -sum(f_nodes), it is
    the work on the relative motion: the change of the stored penalty energy plus the
    (negative) friction and damping work. Sum it over ranks.
    """
    dt = _positive("dt", dt)
    f = np.asarray(f_nodes, dtype=float)
    v_mid = 0.5 * (np.asarray(v_old, dtype=float) + np.asarray(v_new, dtype=float))
    if f.shape != v_mid.shape:
        raise ValueError(f"f_nodes {f.shape} and velocities {v_mid.shape} differ in shape")
    fp_z = float(np.asarray(f_projectile, dtype=float)[2])
    vz_mid = 0.5 * (_finite("vz_old", vz_old) + _finite("vz_new", vz_new))
    return float(dt * (np.einsum("ij,ij->", f, v_mid) + fp_z * vz_mid))


def critical_omega_dt(damping_ratio: float = 0.0) -> float:
    """Stability limit of omega*dt for a spring-dashpot node in the explicit central-difference
    scheme with the damping force taken from the lagged half-step velocity:
    omega dt < 2 (sqrt(1 + zeta^2) - zeta), which is 2 for zeta = 0.

    (Amplification matrix [[1-a, 1-b], [-a, 1-b]] with a = (omega dt)^2, b = 2 zeta omega dt:
    det = 1 - b, trace = 2 - a - b; Jury's conditions give a + 2 b < 4.)
    """
    zeta = _finite("damping_ratio", damping_ratio)
    if zeta < 0.0:
        raise ValueError(f"damping_ratio must be >= 0, got {zeta!r}")
    return 2.0 * (math.sqrt(1.0 + zeta * zeta) - zeta)


def stable_penalty(
    nodal_mass: Any, dt: float, fraction: float = 0.5, damping_ratio: float = 0.0
) -> np.ndarray:
    """Per-node penalty stiffness k = m (fraction * omega_crit dt / dt)^2, with omega_crit dt
    from :func:`critical_omega_dt` (2 undamped, 0.83 at critical damping).

    The node on its penalty spring is an oscillator of frequency sqrt(k/m); central difference
    is stable for omega dt < omega_crit dt. Scaling with m / dt^2 keeps the penalty stable under
    mesh refinement and as stiff as the step allows. The safety fraction covers two things:

    * the membrane stiffness the node also feels: the fabric's step uses a Courant fraction C
      of its own limit, and the combined node stays stable when roughly C^2 + fraction^2 < 1;
    * the one-sided spring: switching on/off inside a step is not energy-neutral. A node
      dropped on the face (tests/fem/test_projectile.py) keeps its energy to within about
      (omega dt)^2 / 4 (1 % at omega dt = 0.2) but can *gain* energy near the limit (+55 % at
      fraction 0.6 undamped), which :class:`PenaltyContact` forbids by capping the fraction
      at 0.5. With critical damping, fraction 0.5 gives omega dt = 0.41.
    """
    dt = _positive("dt", dt)
    fraction = _positive("fraction", fraction)
    if fraction > 1.0:
        raise ValueError(f"fraction must be in (0, 1], got {fraction!r}")
    m = np.asarray(nodal_mass, dtype=float)
    _per_node("nodal_mass", m.ravel(), m.size)
    return _penalty(m, dt, fraction, damping_ratio)


def _penalty(m: np.ndarray, dt: float, fraction: float, damping_ratio: float) -> np.ndarray:
    """:func:`stable_penalty` of arguments already checked (masses > 0, dt > 0, fraction in
    (0, 1], damping_ratio >= 0)."""
    wdt = fraction * critical_omega_dt(damping_ratio)
    return m * (wdt / dt) ** 2


class PenaltyContact:
    """Node-to-rigid-surface penalty contact with Coulomb friction between the fabric nodes
    and a :class:`Projectile` (face, fillet and side).

    penalty: None (default) = :func:`stable_penalty` of each node's mass and the step, with
    ``penalty_fraction`` (<= 0.5) and the damping ratio; or a scalar / per-node array in N/m,
    checked at every call against half the stability limit. damping_ratio: fraction of
    critical damping of the node-on-penalty oscillator (default 1: see below). friction:
    Coulomb coefficient, default the projectile's.

    Measured first-touch spike (free nodes of 0.158 kg/m^2 on a 1 mm grid, dt = 1e-7 s,
    57.3 m/s, sharp edge): about 45 kN for one or two steps with or without damping. It is
    the impulse rho_A pi R^2 v0 of the fabric under the flat face delivered within the
    contact time, so its height scales with 1/dt; what differs is the node speed after it
    (2 v0 undamped, 1.14 v0 at zeta = 1), and that is what strains the yarns.

    Why critical damping by default: an undamped penalty makes every fabric node that the
    projectile meets bounce off the face at up to twice the impact speed and come back; the
    repeated impacts are the contact chatter (force peaks of several times the mean, a
    kilonewton spike at first touch) that otherwise reaches the yarn stretch and the damage.
    ABAQUS's kinematic contact, which the thesis used, makes node impacts perfectly plastic;
    zeta = 1 with the no-adhesion clip gives a nearly plastic node impact (a node dropped on
    the face keeps at most 3 % of its energy, restitution <= 0.17, and never gains energy)
    while keeping the penalty explicit and stable. A softer penalty alone would not do: the
    impulse m v needed to bring a node to the projectile's speed is the same, and undamped
    nodes still rebound. The energy the dashpot takes is booked in ``info["damping_work"]``.
    """

    def __init__(
        self,
        projectile: Projectile,
        penalty: Any = None,
        damping_ratio: float = 1.0,
        friction: float | None = None,
        penalty_fraction: float = 0.5,
    ) -> None:
        if not isinstance(projectile, Projectile):
            raise ValueError(f"projectile must be a Projectile, got {type(projectile).__name__}")
        self.projectile = projectile
        self.damping_ratio = _finite("damping_ratio", damping_ratio)
        if self.damping_ratio < 0.0:
            raise ValueError(f"damping_ratio must be >= 0, got {damping_ratio!r}")
        mu = projectile.friction if friction is None else _finite("friction", friction)
        if mu < 0.0:
            raise ValueError(f"friction must be >= 0, got {friction!r}")
        self.friction = mu
        self.penalty_fraction = _positive("penalty_fraction", penalty_fraction)
        if self.penalty_fraction > _MAX_PENALTY_FRACTION:
            raise ValueError(
                f"penalty_fraction must be in (0, {_MAX_PENALTY_FRACTION}], got "
                f"{penalty_fraction!r}: a stiffer one-sided penalty gains energy at contact"
            )
        if penalty is not None:
            k = np.asarray(penalty, dtype=float)
            _per_node("penalty", k.ravel(), k.size)
            if k.ndim > 1:
                raise ValueError(f"penalty must be a scalar or 1-D, got shape {k.shape}")
            penalty = k
        self.penalty = penalty

    def _stiffness(self, m: np.ndarray, dt: float, idx: np.ndarray, n: int) -> np.ndarray:
        if self.penalty is None:   # m and dt checked by forces, the rest by __init__
            return _penalty(m, dt, self.penalty_fraction, self.damping_ratio)
        if self.penalty.ndim == 1 and self.penalty.shape[0] != n:
            raise ValueError(f"penalty has {self.penalty.shape[0]} entries for {n} nodes")
        k = np.broadcast_to(self.penalty, (n,))[idx]
        k_max = stable_penalty(m, dt, _MAX_PENALTY_FRACTION, self.damping_ratio)
        if np.any(k > k_max):
            i = int(np.argmax(k / k_max))
            raise ValueError(
                f"penalty {k[i]:.4g} N/m exceeds {k_max[i]:.4g} N/m, {_MAX_PENALTY_FRACTION} of "
                f"the central-difference stability limit for nodal mass {m[i]:.4g} kg, dt "
                f"{dt:.4g} s and damping ratio {self.damping_ratio}: lower the penalty or dt "
                "(or pass penalty=None)"
            )
        return k

    def forces(
        self, x: Any, v: Any, nodal_mass: Any, dt: float, state: ProjectileState
    ) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
        """Contact forces at step n.

        x (n, 3): nodal positions x^n; v (n, 3): nodal velocities v^(n-1/2); nodal_mass: lumped
        masses (scalar or (n,)); dt: the step; state: the projectile (z^n, vz^(n-1/2)).

        Returns f_nodes (n, 3) on the nodes, f_projectile (3,) = -sum(f_nodes) on the
        projectile, and info with this rank's sums: penalty_energy = sum 1/2 k p^2 (J, stored),
        friction_work = sum f_t . v_rel dt and damping_work = sum f_damp . v_rel dt (J, both
        <= 0), n_active, n_released (dashpot would have pulled, clipped to zero), n_sliding
        (friction at the Coulomb limit), max_penetration (m), normal_force and
        friction_force (sums of magnitudes, N).

        friction_work and damping_work use the lagged v^(n-1/2) and are first-order estimates
        of the split (a critically damped node impact at omega dt = 0.41 books about 1.8x the
        energy it loses). For an exact energy balance use :func:`contact_work` with the
        velocities before and after the step: contact dissipation = -sum(contact_work) minus
        the change of penalty_energy.
        """
        x = _points("x", x)
        v = _points("v", v)
        n = x.shape[0]
        if v.shape[0] != n:
            raise ValueError(f"v has {v.shape[0]} rows for {n} nodes in x")
        dt = _positive("dt", dt)
        mass_all = _per_node("nodal_mass", nodal_mass, n)
        if not isinstance(state, ProjectileState):
            raise ValueError(f"state must be a ProjectileState, got {type(state).__name__}")

        proj = self.projectile
        f_nodes = np.zeros((n, 3))
        zf = proj._z_face(state.z)
        idx, pen, nrm = np.empty(n, np.int64), np.empty(n), np.empty((n, 3))
        n_in, pen_max = _inside(np.ascontiguousarray(x), zf, proj.length, proj.radius, 0.5 * proj.length,
                                proj.fillet, proj.axis_xy[0], proj.axis_xy[1], proj.radius**2, idx, pen,
                                nrm)
        idx, pen, nrm = idx[:n_in], pen[:n_in], nrm[:n_in]
        if idx.size == 0:
            return f_nodes, np.zeros(3), dict(
                penalty_energy=0.0, friction_work=0.0, damping_work=0.0, n_active=0,
                n_released=0, n_sliding=0, max_penetration=0.0, normal_force=0.0,
                friction_force=0.0,
            )

        limit = _MAX_PENETRATION_FRACTION * min(proj.radius, 0.5 * proj.length)
        if pen_max > limit:
            i = int(np.argmax(pen))
            raise RuntimeError(
                f"PenaltyContact.forces: node {int(idx[i])} at {x[idx[i]]} penetrates "
                f"{pen[i]:.4g} m into the projectile (limit {limit:.4g} m, face at "
                f"z = {state.z:.6g}): the penalty is too soft for the impact speed or the "
                "projectile started inside the fabric; reduce dt or check z0"
            )
        m = mass_all[idx]
        k = self._stiffness(m, dt, idx, n)
        # Per node (compiled, contact_kernel.penalty_forces): normal force k p + c pdot with
        # c = 2 zeta sqrt(k m); contact cannot be adhesive: when the dashpot would pull the
        # separating node back onto the face, the node is released (force 0) instead. Friction
        # min(mu f_n, m |v_t| / dt) against the relative sliding v_t: the stick cap never lets
        # friction reverse v_t in one step (explicit, history-free regularisation: the
        # regularising velocity is mu f_n dt / m).
        sums = np.empty(10)
        penalty_forces(idx, np.ascontiguousarray(pen), np.ascontiguousarray(nrm), v,
                       np.ascontiguousarray(m), np.ascontiguousarray(k, dtype=float), state.vz,
                       self.damping_ratio, self.friction, dt, f_nodes, sums)
        info = dict(
            penalty_energy=float(sums[0]), friction_work=float(sums[1]), damping_work=float(sums[2]),
            n_active=int(idx.size), n_released=int(sums[3]), n_sliding=int(sums[4]),
            max_penetration=float(pen_max), normal_force=float(sums[5]), friction_force=float(sums[6]),
        )
        return f_nodes, sums[7:10].copy(), info
