"""Analytic verification of the explicit membrane dynamics: J. C. Smith's transverse impact.

A long, straight, crimp-free strip of linear, tension-only yarns (tension per unit reference width
T = k (lambda - 1), areal density rho_A of the reference fabric) is struck at X = 0 by a rigid bar
that spans its whole width and moves perpendicular to the strip at the constant speed V.  The
problem is one-dimensional (a string with line density rho_A and tension T per unit width) and
self-similar; its solution is the classical theory of transverse impact on a yarn
(J. C. Smith, F. L. McCrackin and H. F. Schiefer, "Stress-strain relationships in yarns subjected
to rapid impact loading, Part V: Wave propagation in long textile yarns impacted transversely",
Textile Research Journal 28 (1958) 288-302, here for a linear stress-strain law; the relations
below are re-derived from the jump conditions and checked in tests/studies/test_smith.py):

* a longitudinal (strain) wave runs along the strip at c = sqrt(k / rho_A) (Lagrangian speed,
  equal to its laboratory speed because the material ahead is at rest); behind it the strip
  carries the uniform engineering strain eps and flows towards the impact point at c eps;
* a transverse wave (a kink) follows at the Lagrangian speed W = c sqrt(eps / (1 + eps)); between
  the bar and the kink the strip is a straight, inclined segment with the same strain eps,
  at rest horizontally and moving with the bar;
* in the laboratory the kink travels at U = c (sqrt(eps (1 + eps)) - eps) (Smith et al. 1958);
* eps follows from V through Smith's relation V = c sqrt(2 eps sqrt(eps (1 + eps)) - eps^2).

Derivation (jump conditions of the string rho_A x_tt = d(T tau)/dX, tau the unit tangent, at a
front moving at the Lagrangian speed W: compatibility [x_t] = -W [x_X], momentum
-W rho_A [x_t] = [T tau]).  At the longitudinal front (rest ahead, x_X = (1 + eps) e_x behind)
they give the particle velocity -c eps e_x and W = c.  At the kink (ahead: x_X = (1 + eps) e_x,
x_t = -c eps e_x; behind: x_X = (1 + eps) (cos th, sin th), x_t = -V e_z) the tension is
continuous, so W^2 = T / (rho_A (1 + eps)) = c^2 eps / (1 + eps), and
c eps = W (1 + eps)(1 - cos th), V = W (1 + eps) sin th.  The kink's laboratory speed is
U = W (1 + eps) - c eps.  Eliminating th: V^2 = c^2 eps (1 + eps) - U^2, which is Smith's
relation.  For small strains V ~ c sqrt(2) eps^(3/4), i.e. eps ~ (V / c)^(4/3) / 2^(2/3).

The module has two parts: the closed form (pure vectorised numpy), and `simulate_transverse_impact`,
which runs the project's explicit membrane solver (`fabric_fenicsx.fem.explicit.CentralDifference`
with `LinearYarnMaterial`) on a strip and measures the same quantities.  DOLFINx is imported only
by the driver.

Simulation set-up (symmetric half strip, SI units): reference strip 0 <= X <= L, |Y| <= width/2,
quadrilaterals, warp (yarn 1) along X (material angle 0), fill stiffness equal to the warp's (it
stays unstrained: the motion is uniform across the width).  The bar line X = 0 is the symmetry
plane: all its dofs are prescribed, u_x = u_y = 0 and u_z = -V t (they are in the integrator's
"clamped" set, whose velocity stays what it was set to: v = (0, 0, -V) from t = 0).  The far end
X = L is clamped.  The run stops when the longitudinal front has travelled `end_fraction` L, so
nothing reflected from the far end is ever measured.  Every step the nodes of the row Y = -width/2
are recorded (the solution is uniform across the width; this is checked at the end against the
strains of every quadrature point).

Measured quantities (all from that row; the strain of the segment between two neighbouring nodes
equals the yarn strain lambda_1 - 1 of the bilinear elements there, because the field does not
vary across the width):

* plateau strain behind the longitudinal wave: at each recorded time, the mean segment strain over
  the middle half of the straight region between the transverse and the longitudinal fronts,
  [X_T + (X_L - X_T)/4, X_L - (X_L - X_T)/4]; reported as the average of that mean over the
  fit window (below); `strain_inclined` is the same average over the middle half of the inclined
  segment, [X_T / 4, 3 X_T / 4] (Smith: the same eps);
* longitudinal front X_L(t): the last (largest-X) point where the segment strain reaches half the
  current plateau (linear interpolation between segment midpoints); the current plateau used for
  that level is the median segment strain over all segments behind the point where the strain
  last exceeds a quarter of its maximum (robust to the numerical overshoot at the front);
* transverse front (kink): the inclined segment between bar and kink is straight, so the kink is
  located where the straight line fitted (least squares) to the nodes whose deflection |u_z| lies
  between 20 % and 80 % of the bar deflection V t (that of the bar node) meets the undeflected level u_z = 0; in the
  reference coordinate (u_z against X, Lagrangian position X_T) and in the laboratory
  (u_z against X + u_x, laboratory position x_T);
* the speeds c, W, U are the slopes of straight lines fitted by least squares to X_L(t), X_T(t),
  x_T(t) over the fit window t >= fit_start_fraction * t_end (start-up transients excluded).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

__all__ = [
    "longitudinal_wave_speed", "impact_velocity", "strain_behind_wave",
    "small_strain_limit", "transverse_wave_speed_lab", "transverse_wave_speed_material",
    "kink_angle", "SmithTheory", "smith_theory", "SmithSimulation", "simulate_transverse_impact",
]


# ============================================================================ closed form
def _as_nonnegative(name: str, value) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return a


def _as_positive(name: str, value) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return a


def longitudinal_wave_speed(stiffness, areal_density):
    """Longitudinal (strain) wave speed c = sqrt(k / rho_A) (m/s) of a linear yarn layer with
    tension per unit reference width T = k (lambda - 1) (k in N/m) and reference areal density
    rho_A (kg/m^2): the 1D wave equation rho_A u_tt = k u_XX (Smith et al. 1958, c = sqrt(E/rho))."""
    return np.sqrt(_as_positive("stiffness", stiffness) / _as_positive("areal_density", areal_density))


def impact_velocity(strain, wave_speed):
    """Smith's relation (Smith, McCrackin & Schiefer 1958) for a linear yarn: the transverse
    impact speed V (m/s) that produces the engineering strain eps behind the longitudinal wave,

        V = c sqrt(2 eps sqrt(eps (1 + eps)) - eps^2),

    c the longitudinal wave speed (m/s).  Monotonic increasing in eps >= 0."""
    eps = _as_nonnegative("strain", strain)
    c = _as_positive("wave_speed", wave_speed)
    return c * np.sqrt(2.0 * eps * np.sqrt(eps * (1.0 + eps)) - eps * eps)


def strain_behind_wave(velocity, wave_speed, rtol: float = 1e-14):
    """Engineering strain eps behind the longitudinal wave for the impact speed V (m/s): the root
    of Smith's relation V = c sqrt(2 eps sqrt(eps (1 + eps)) - eps^2) (`impact_velocity`).

    Vectorised bisection on the bracket [0, V/c]: g(eps) = 2 eps sqrt(eps (1 + eps)) - eps^2 is
    strictly increasing for eps > 0 and g(eps) >= eps^2, so g(V/c) >= (V/c)^2 and the root is
    unique and inside the bracket.  Bisection stops when the bracket is below rtol * eps."""
    V = _as_nonnegative("velocity", velocity)
    c = _as_positive("wave_speed", wave_speed)
    if not (0 < rtol < 1):
        raise ValueError(f"rtol must be in (0, 1), got {rtol!r}")
    v = np.broadcast_to(V / c, np.broadcast(V, c).shape).astype(float)
    target = v * v
    lo, hi = np.zeros_like(v), v.copy()
    for _ in range(200):  # 2^-200 of the bracket is far below any rtol
        mid = 0.5 * (lo + hi)
        g = 2.0 * mid * np.sqrt(mid * (1.0 + mid)) - mid * mid
        below = g < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
        if np.all(hi - lo <= rtol * hi):
            break
    eps = 0.5 * (lo + hi)
    return eps if eps.ndim else float(eps)


def small_strain_limit(velocity, wave_speed):
    """Leading-order inversion of Smith's relation for V << c: V^2 / c^2 = 2 eps^(3/2) - eps^2
    + O(eps^(5/2)), so eps0 = (V / c)^(4/3) / 2^(2/3); the exact strain is
    eps = eps0 (1 + sqrt(eps0) / 3 + O(eps0))."""
    V = _as_nonnegative("velocity", velocity)
    c = _as_positive("wave_speed", wave_speed)
    return (V / c) ** (4.0 / 3.0) / 2.0 ** (2.0 / 3.0)


def transverse_wave_speed_lab(strain, wave_speed):
    """Laboratory-frame speed of the transverse wave (kink), U = c (sqrt(eps (1 + eps)) - eps)
    (Smith et al. 1958): the Lagrangian kink speed times the stretch, W (1 + eps), minus the inward
    flow c eps of the material ahead of the kink."""
    eps = _as_nonnegative("strain", strain)
    return _as_positive("wave_speed", wave_speed) * (np.sqrt(eps * (1.0 + eps)) - eps)


def transverse_wave_speed_material(strain, wave_speed):
    """Lagrangian (material-frame) speed of the transverse wave, W = c sqrt(eps / (1 + eps)) =
    sqrt(T / (rho_A lambda)): a string wave under the tension T = k eps per unit reference width
    with the line density rho_A / lambda of the stretched strip, expressed per reference length."""
    eps = _as_nonnegative("strain", strain)
    return _as_positive("wave_speed", wave_speed) * np.sqrt(eps / (1.0 + eps))


def kink_angle(strain):
    """Angle th (rad) of the inclined segment to the undeformed strip, from the horizontal jump
    condition at the kink, c eps = W (1 + eps)(1 - cos th) with W = c sqrt(eps / (1 + eps)):
    cos th = 1 - sqrt(eps / (1 + eps))."""
    eps = _as_nonnegative("strain", strain)
    return np.arccos(1.0 - np.sqrt(eps / (1.0 + eps)))


@dataclasses.dataclass(frozen=True)
class SmithTheory:
    """Closed-form Smith solution for one impact (SI units)."""
    impact_velocity: float        # V (m/s)
    wave_speed: float             # c = sqrt(k / rho_A) (m/s)
    strain: float                 # eps behind the longitudinal wave
    transverse_speed_lab: float   # U (m/s)
    transverse_speed_material: float  # W (m/s, per reference length)
    tension: float                # T = k eps (N/m)
    inflow_speed: float           # c eps (m/s), material speed towards the impact point


def smith_theory(velocity: float, stiffness: float, areal_density: float) -> SmithTheory:
    """The Smith solution for the impact speed V (m/s) on a linear yarn layer k (N/m), rho_A
    (kg/m^2)."""
    V = float(_as_positive("velocity", velocity))
    k = float(_as_positive("stiffness", stiffness))
    c = float(longitudinal_wave_speed(k, areal_density))
    eps = float(strain_behind_wave(V, c))
    return SmithTheory(V, c, eps, float(transverse_wave_speed_lab(eps, c)),
                       float(transverse_wave_speed_material(eps, c)), k * eps, c * eps)


# ============================================================================ simulation
@dataclasses.dataclass(frozen=True)
class SmithSimulation:
    """Measured and theoretical values of one strip run (SI units); see the module docstring for
    how the fronts are defined.  `errors` maps quantity -> |measured - theory| / theory."""
    theory: SmithTheory
    n_elements: int               # elements along the half length
    element_size: float           # h (m) along the strip
    dt: float
    n_steps: int
    end_time: float
    strain: float                 # plateau strain behind the longitudinal wave
    strain_inclined: float        # mean strain of the middle half of the inclined segment
    longitudinal_speed: float     # c, fitted
    transverse_speed_lab: float   # U, fitted
    transverse_speed_material: float  # W, fitted
    max_width_variation: float    # max |lambda1 - 1 - row strain| over all quadrature points
    max_fill_strain: float        # max |E2| over all quadrature points (0 in the 1D problem)
    wall_time: float
    times: np.ndarray = dataclasses.field(repr=False)
    longitudinal_front: np.ndarray = dataclasses.field(repr=False)   # X_L(t)
    transverse_front: np.ndarray = dataclasses.field(repr=False)     # X_T(t), Lagrangian
    transverse_front_lab: np.ndarray = dataclasses.field(repr=False)  # x_T(t), laboratory
    plateau_history: np.ndarray = dataclasses.field(repr=False)
    fit_mask: np.ndarray = dataclasses.field(repr=False)
    node_x: np.ndarray = dataclasses.field(repr=False)       # reference X of the row nodes
    final_ux: np.ndarray = dataclasses.field(repr=False)
    final_uz: np.ndarray = dataclasses.field(repr=False)
    final_segment_strain: np.ndarray = dataclasses.field(repr=False)

    @property
    def errors(self) -> dict:
        th = self.theory
        pairs = {"strain": (self.strain, th.strain),
                 "strain_inclined": (self.strain_inclined, th.strain),
                 "longitudinal_speed": (self.longitudinal_speed, th.wave_speed),
                 "transverse_speed_lab": (self.transverse_speed_lab, th.transverse_speed_lab),
                 "transverse_speed_material": (self.transverse_speed_material,
                                               th.transverse_speed_material)}
        return {k: abs(m - t) / t for k, (m, t) in pairs.items()}

    def summary(self) -> dict:
        """Plain dict of the scalars (for CSV / JSON)."""
        th = self.theory
        d = {"V": th.impact_velocity, "n_elements": self.n_elements, "h": self.element_size,
             "dt": self.dt, "n_steps": self.n_steps, "end_time": self.end_time,
             "strain_theory": th.strain, "strain_sim": self.strain,
             "strain_inclined_sim": self.strain_inclined,
             "c_theory": th.wave_speed, "c_sim": self.longitudinal_speed,
             "U_theory": th.transverse_speed_lab, "U_sim": self.transverse_speed_lab,
             "W_theory": th.transverse_speed_material, "W_sim": self.transverse_speed_material,
             "max_width_variation": self.max_width_variation,
             "max_fill_strain": self.max_fill_strain, "wall_time": self.wall_time}
        d.update({f"err_{k}": v for k, v in self.errors.items()})
        return d


def segment_strain(node_x: np.ndarray, ux: np.ndarray, uz: np.ndarray) -> np.ndarray:
    """Engineering strain |d(X + u)| / dX - 1 of the segments between consecutive row nodes
    (node_x increasing), for displacement histories ux, uz of shape (..., n_nodes)."""
    dX = np.diff(node_x)
    return np.hypot(dX + np.diff(ux, axis=-1), np.diff(uz, axis=-1)) / dX - 1.0


def longitudinal_front(seg_mid: np.ndarray, strain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Longitudinal front X_L and the current plateau estimate for strain histories (n_t, n_seg)
    at the segment midpoints seg_mid: X_L is the largest X where the strain reaches half the
    plateau (linear interpolation); the plateau is the median strain behind the last point where
    the strain exceeds a quarter of its maximum.  NaN where nothing is strained yet."""
    n_t, n_seg = strain.shape
    smax = strain.max(axis=1, keepdims=True)
    strained = (strain > 0.25 * smax) & (smax > 0)
    last = n_seg - 1 - np.argmax(strained[:, ::-1], axis=1)
    behind = np.arange(n_seg)[np.newaxis, :] <= last[:, np.newaxis]
    plateau = np.nanmedian(np.where(behind, strain, np.nan), axis=1)
    level = 0.5 * plateau
    above = strain >= level[:, np.newaxis]
    j = n_seg - 1 - np.argmax(above[:, ::-1], axis=1)     # last segment at or above the level
    jn = np.minimum(j + 1, n_seg - 1)
    rows = np.arange(n_t)
    s0, s1 = strain[rows, j], strain[rows, jn]
    frac = np.where(s0 > s1, (s0 - level) / np.where(s0 > s1, s0 - s1, 1.0), 0.0)
    front = seg_mid[j] + np.clip(frac, 0.0, 1.0) * (seg_mid[jn] - seg_mid[j])
    valid = (smax[:, 0] > 0) & np.isfinite(plateau) & (plateau > 0)
    return np.where(valid, front, np.nan), np.where(valid, plateau, np.nan)


def kink_position(position: np.ndarray, deflection: np.ndarray, bar_deflection: np.ndarray,
                  band=(0.2, 0.8)) -> np.ndarray:
    """Kink location where the straight line fitted (least squares) to the nodes with
    band[0] <= deflection / bar_deflection <= band[1] meets zero deflection.

    position, deflection: (n_t, n_nodes) histories (deflection = -u_z >= 0 behind the kink);
    bar_deflection: (n_t,).  Only nodes up to the first one below band[0] count (the ramp next to
    the bar).  NaN where fewer than two nodes are in the band."""
    with np.errstate(invalid="ignore", divide="ignore"):
        r = deflection / bar_deflection[:, np.newaxis]
    below = ~(r >= band[0])
    first_below = np.where(below.any(axis=1), np.argmax(below, axis=1), r.shape[1])
    ramp = np.arange(r.shape[1])[np.newaxis, :] < first_below[:, np.newaxis]
    w = (ramp & (r <= band[1])).astype(float)
    n = w.sum(axis=1)
    sx, sz = (w * position).sum(axis=1), (w * deflection).sum(axis=1)
    sxx, sxz = (w * position ** 2).sum(axis=1), (w * position * deflection).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (n * sxz - sx * sz) / (n * sxx - sx * sx)
        intercept = (sz - slope * sx) / n
        root = -intercept / slope
    return np.where((n >= 2) & (slope < 0), root, np.nan)


def _fit_speed(t: np.ndarray, x: np.ndarray, mask: np.ndarray, name: str) -> float:
    ok = mask & np.isfinite(x)
    if ok.sum() < 3:
        raise RuntimeError(f"too few samples ({ok.sum()}) of the {name} in the fit window; "
                           "refine the mesh or lengthen the run")
    return float(np.polyfit(t[ok], x[ok], 1)[0])


def simulate_transverse_impact(velocity: float, n_elements: int, *, stiffness: float = 5.0e5,
                               areal_density: float = 0.158, half_length: float = 1.0,
                               width: float = 0.02, elements_across: int = 2,
                               dt_safety: float = 0.9, end_fraction: float = 0.85,
                               fit_start_fraction: float = 0.3) -> SmithSimulation:
    """Run the explicit membrane solver on the half strip struck by a bar at constant `velocity`
    (m/s) and measure the Smith quantities (module docstring).  Serial (MPI.COMM_SELF).

    Args:
        velocity: bar speed V (m/s), > 0.
        n_elements: elements along the half length (h = half_length / n_elements).
        stiffness: warp (and fill) yarn stiffness k (N/m) of `LinearYarnMaterial`.
        areal_density: rho_A (kg/m^2).
        half_length, width: strip dimensions L and its width (m).
        elements_across: elements across the width.
        dt_safety: factor on the Courant limit `CentralDifference.stable_dt`.
        end_fraction: the run ends when c t = end_fraction * half_length (< 1: no reflection).
        fit_start_fraction: the fit window is t >= fit_start_fraction * end time.
    """
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    from fabric_fenicsx.fem.explicit import CentralDifference, LinearYarnMaterial
    from fabric_fenicsx.fem.membrane import Membrane

    if isinstance(n_elements, bool) or int(n_elements) != n_elements or n_elements < 4:
        raise ValueError(f"n_elements must be an integer >= 4, got {n_elements!r}")
    if isinstance(elements_across, bool) or int(elements_across) != elements_across \
            or elements_across < 1:
        raise ValueError(f"elements_across must be an integer >= 1, got {elements_across!r}")
    for name, value in (("half_length", half_length), ("width", width)):
        _as_positive(name, value)
    if not (0 < end_fraction < 1):
        raise ValueError(f"end_fraction must be in (0, 1) (no reflection), got {end_fraction!r}")
    if not (0 <= fit_start_fraction < 1):
        raise ValueError(f"fit_start_fraction must be in [0, 1), got {fit_start_fraction!r}")
    theory = smith_theory(velocity, stiffness, areal_density)
    n, L, b = int(n_elements), float(half_length), float(width)
    t_wall = time.perf_counter()

    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, -b / 2]), np.array([L, b / 2])],
                                 [n, int(elements_across)], dmesh.CellType.quadrilateral)
    m = Membrane(msh, angle=0.0)
    tol = 1e-9 * L
    bar = m.boundary_dofs(lambda x: np.abs(x[0]) < tol)
    far = m.boundary_dofs(lambda x: np.abs(x[0] - L) < tol)
    cd = CentralDifference(m, LinearYarnMaterial(stiffness, stiffness), areal_density,
                           np.concatenate([bar, far]))
    bar_z = bar[bar % 3 == 2]
    cd.v[bar_z] = -theory.impact_velocity  # prescribed bar motion u_z = -V t (zero acceleration)

    xyz = m.V.tabulate_dof_coordinates()[:m.n_owned_nodes]
    row = np.nonzero(np.abs(xyz[:, 1] + b / 2) < tol)[0]
    row = row[np.argsort(xyz[row, 0])]
    node_x = xyz[row, 0]
    if row.size != n + 1:
        raise RuntimeError(f"expected {n + 1} nodes on the row Y = -width/2, found {row.size}")

    dt = cd.stable_dt(dt_safety)
    end_time = end_fraction * L / theory.wave_speed
    n_steps = int(np.ceil(end_time / dt))
    times = np.empty(n_steps + 1)
    ux = np.empty((n_steps + 1, row.size))
    uz = np.empty((n_steps + 1, row.size))
    u3 = cd.u.reshape(-1, 3)
    times[0], ux[0], uz[0] = 0.0, u3[row, 0], u3[row, 2]
    for i in range(1, n_steps + 1):
        cd.step(dt)
        times[i], ux[i], uz[i] = cd.time, u3[row, 0], u3[row, 2]

    # Uniformity across the width: every quadrature point against the row's segment strain.
    strain = segment_strain(node_x, ux, uz)
    E1, E2 = m.yarn_strains()
    qx = _quadrature_x(m)
    seg = np.clip(np.searchsorted(node_x, qx) - 1, 0, n - 1)
    max_width_variation = float(np.max(np.abs(np.sqrt(1 + 2 * E1) - 1 - strain[-1, seg])))
    max_fill_strain = float(np.max(np.abs(E2)))

    seg_mid = 0.5 * (node_x[1:] + node_x[:-1])
    X_L, plateau_now = longitudinal_front(seg_mid, strain)
    bar_deflection = -uz[:, 0]
    X_T = kink_position(np.broadcast_to(node_x, uz.shape), -uz, bar_deflection)
    x_T = kink_position(node_x + ux, -uz, bar_deflection)

    fit = times >= fit_start_fraction * times[-1]
    # Plateau: middle half of the straight region between the fronts, averaged over the window.
    lo = X_T + 0.25 * (X_L - X_T)
    hi = X_L - 0.25 * (X_L - X_T)
    in_straight = (seg_mid >= lo[:, None]) & (seg_mid <= hi[:, None])
    in_incl = (seg_mid >= 0.25 * X_T[:, None]) & (seg_mid <= 0.75 * X_T[:, None])
    with np.errstate(invalid="ignore"):
        straight_mean = np.where(in_straight, strain, 0).sum(1) / in_straight.sum(1)
        incl_mean = np.where(in_incl, strain, 0).sum(1) / in_incl.sum(1)
    ok = fit & np.isfinite(straight_mean)
    ok_incl = fit & np.isfinite(incl_mean)
    if not ok.any() or not ok_incl.any():
        raise RuntimeError("no sample with both fronts located in the fit window; refine the mesh")

    return SmithSimulation(
        theory=theory, n_elements=n, element_size=L / n, dt=dt, n_steps=n_steps,
        end_time=float(times[-1]),
        strain=float(straight_mean[ok].mean()), strain_inclined=float(incl_mean[ok_incl].mean()),
        longitudinal_speed=_fit_speed(times, X_L, fit, "longitudinal front"),
        transverse_speed_lab=_fit_speed(times, x_T, fit, "laboratory kink position"),
        transverse_speed_material=_fit_speed(times, X_T, fit, "Lagrangian kink position"),
        max_width_variation=max_width_variation, max_fill_strain=max_fill_strain,
        wall_time=time.perf_counter() - t_wall,
        times=times, longitudinal_front=X_L, transverse_front=X_T, transverse_front_lab=x_T,
        plateau_history=straight_mean, fit_mask=fit, node_x=node_x, final_ux=ux[-1].copy(),
        final_uz=uz[-1].copy(), final_segment_strain=strain[-1].copy())


def _quadrature_x(m) -> np.ndarray:
    """Reference X coordinate of every owned quadrature point of the membrane (cell-major)."""
    import basix
    import ufl
    from dolfinx import fem

    points, _ = basix.make_quadrature(basix.CellType.quadrilateral, m.quadrature_degree)
    expr = fem.Expression(ufl.SpatialCoordinate(m.msh)[0], points)
    return expr.eval(np.arange(m.n_cells, dtype=np.int32)).ravel()
