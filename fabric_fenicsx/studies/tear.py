"""The tear test: a fabric panel with a slit across the loaded yarns, pulled until the tear runs.

A square panel (default 60 mm, warp along x) is clamped along its left edge; its right edge
moves at a constant speed along x (default 5 m/s, a strain rate of 83 /s, as the strip test's
100 /s), so that the warp carries the load. A slit cuts the warp yarns along y at x = 0: from the
bottom edge (``notch = "edge"``) or about the centre (``"centre"``), made by removing the cells
it crosses (``slit_cut = "cells"``) or by cutting their warp yarns only (``"warp"``: alpha1 = 0,
the fill yarns along the slit kept, a crack band as a broken warp leaves it). The membrane, the
reduced element with its hourglass control, the surrogate, the damping and the removal rules
(deletion when both yarns are broken, erosion at ``erosion_strain``) are the impact scenes'; the
failure rule is the thesis's or a candidate (``failure``: ``yarn_crack``, ``yarn_tip``,
``yarn_strain``, ``shear_lag``, ``del_zone``, ``del_zone_budget``, ``yarn_average``).

The panel is meshed with cells of one size ``h`` (the tear's tip meets the same cells all the
way) in families that tell the cells' orientation from their shape:

* ``aligned``: a grid of squares along the yarns;
* ``structured<deg>``, e.g. ``structured30``, ``structured45``: squares of side h in rows turned
  that many degrees from the yarns over the middle of the panel
  (:mod:`fabric_fenicsx.fem.structured_patch`), unstructured quadrilaterals of size h around;
* ``graded``: gmsh's unstructured quadrilaterals (the graded scenes' mesher) at size h;
* ``file``: a user's gmsh file of the panel (:func:`fabric_fenicsx.fem.mesh_file.read_square_msh`).

A pull reports (:meth:`TearTest.pull`): the **tear load**, the end force when the first cell
beyond the slit breaks (its warp alpha below 1/2, or removed) and joins the slit; the peak force; the **work per
unit length of tear**, the energy given up by the breaking yarns (damage dissipation plus the
stored energy of removed cells) while the tear grew, over its length; and the **path's angle**, the principal direction of the centres of the
tear's cells (the broken cells joined to the slit through broken cells; 90 degrees: along the
fill yarns, straight across the load); the **tear strain**, the uncut section's mean warp Green
strain at the tear load (when the rule tears, apart from the force each mesh carries at that
strain: a grid turned 45 degrees carries up to 15 % more than the aligned one, docs/tear_test.md);
the **cut strain**, the mean warp strain of the slit's cut yarns away from it over the section's
then (:func:`cut_yarn_cells`: 0 or below in the thesis's membrane, whose cut yarns carry nothing;
above, load the cells pass into them);
and the **tip concentration**, the warp strain of the
tear's first cell over that of the uncut section at half the tear load (:func:`tip_concentration`:
1 in the thesis's membrane, whose yarns pass no load to each other; what the cells add depends on
their shape). A tear that follows the yarns has the same load, work and angle on every family;
one that follows the cells does not. ``fabric-fenicsx study tear`` is its command line.
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import asdict, dataclass

import numpy as np

from fabric_fenicsx.fem.crack_bridges import bridge_cells, corner_nodes
from fabric_fenicsx.fem.crack_rules import CRACK_RULES, crack_rule_on_cells
from fabric_fenicsx.fem.yarn_crack import BROKEN_ALPHA

FAILURE_RULES = ("thesis", "yarn_average", *CRACK_RULES)
"""The failure rules a pull can use: the scenes' (``material.failure``) and the yarn average."""

__all__ = ["TearSetup", "parse_family", "slit_cells", "section_cells", "cut_yarn_cells", "near_tip_cells", "tip_concentration",
           "path_angle", "work_per_length", "TearTest"]

@dataclass(frozen=True)
class TearSetup:
    """Geometry and loading of a tear test (SI units; angles in degrees)."""

    side: float = 0.06
    slit: float = 0.01           # length of the slit (m): from the bottom edge, or centred
    notch: str = "edge"          # "edge" | "centre"
    speed: float = 5.0           # m/s, the right edge along x
    damping: float = 0.1         # of critical at the unit cell, as run.damping
    hourglass: float = 0.05
    dt_safety: float = 0.8
    erosion_strain: float = 1.0  # material.erosion_strain
    grips: str = "clamped"       # "clamped" (every component held) | "rollers" (the edges free along y)
    failure: str = "thesis"      # "thesis" | "yarn_average" | one of CRACK_RULES
    failure_length: float = 0.0  # m: the yarn average's length (yarn_average only)
    failure_width: float = 0.0   # m: the yarn average's width across the yarn (0: one cell)
    slit_cut: str = "cells"      # "cells" (the slit's cells removed) | "warp" (their warp cut, alpha1 = 0)

    def __post_init__(self) -> None:
        if self.grips not in ("clamped", "rollers"):
            raise ValueError(f"grips = {self.grips!r}: must be 'clamped' or 'rollers'")
        if self.failure not in FAILURE_RULES:
            raise ValueError(f"failure = {self.failure!r}: must be one of {', '.join(FAILURE_RULES)}")
        if self.failure == "yarn_average" and not self.failure_length > 0:
            raise ValueError(f"failure_length = {self.failure_length!r}: the yarn average needs a length > 0 m")
        if self.slit_cut not in ("cells", "warp"):
            raise ValueError(f"slit_cut = {self.slit_cut!r}: must be 'cells' or 'warp'")
        if self.notch not in ("edge", "centre"):
            raise ValueError(f"notch = {self.notch!r}: must be 'edge' or 'centre'")
        for name in ("side", "slit", "speed", "damping", "hourglass", "dt_safety", "erosion_strain"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r}: must be a finite number > 0")
        if self.hourglass > 1.0:
            raise ValueError(f"hourglass = {self.hourglass!r}: must lie in (0, 1], a fraction of the yarn "
                             "modulus as the scenes' membrane.hourglass")
        if self.slit >= 0.5 * self.side:
            raise ValueError(f"slit = {self.slit!r} m: must be shorter than half the panel ({self.side / 2!r} m)")

    @property
    def slit_ends(self) -> tuple[float, float]:
        """(y0, y1) of the slit along x = 0."""
        a = self.side / 2
        return (-a, -a + self.slit) if self.notch == "edge" else (-self.slit / 2, self.slit / 2)

    def across(self, y: np.ndarray) -> np.ndarray:
        """Positions y (m) across the load as a tear from the slit runs: y for an edge notch, |y|
        for a centred one (it runs both ways); a tear's cells lie past the tip where this exceeds
        ``slit_ends[1]``."""
        return y if self.notch == "edge" else np.abs(y)

    @property
    def ligament(self) -> float:
        """The length the tear can run (m): to the far edge (edge notch) or to one edge (centre)."""
        return self.side - self.slit if self.notch == "edge" else (self.side - self.slit) / 2


def parse_family(family: str) -> tuple[str, float | None]:
    """("aligned" | "structured" | "graded" | "file", rotation in degrees or None) of a family
    name; ``structured30`` is the structured patch at 30 degrees."""
    if family in ("aligned", "graded", "file"):
        return family, None
    m = re.fullmatch(r"structured(-?\d+(?:\.\d+)?)", family)
    if m:
        return "structured", float(m.group(1))
    raise ValueError(f"mesh family {family!r}: must be aligned, graded, file or structured<degrees> "
                     "(e.g. structured30, structured45)")


def panel_mesh(family: str, h: float, setup: TearSetup, comm, mesh_file: str | None = None):
    """The panel [-side/2, side/2]^2 meshed by ``family`` with cells of size ``h`` (module
    docstring). A ``structured`` family's patch is as large as the panel allows."""
    from fabric_fenicsx.fem.mesh import MeshSpec, load_mesh, rectilinear_square
    from fabric_fenicsx.fem.mesh_file import free_rectangle, read_square_msh
    from fabric_fenicsx.fem.structured_patch import largest_patch_radius

    kind, rotation = parse_family(family)
    a = setup.side / 2
    if kind == "aligned":
        n = max(1, round(setup.side / h))
        n += 1 - n % 2            # odd: the slit runs through the middle of a column of cells
        nodes = np.linspace(-a, a, n + 1)
        return rectilinear_square(nodes, nodes, comm)[0]
    if kind == "graded":
        return free_rectangle((-a, -a), (a, a), h, comm)
    if kind == "file":
        if not mesh_file:
            raise ValueError("mesh family 'file' needs a mesh file (--mesh-file)")
        return read_square_msh(mesh_file, setup.side, comm)[0]
    radius = largest_patch_radius(setup.side, (0.0, 0.0), rotation, h)
    radius = math.floor(radius / h) * h
    spec = MeshSpec(side=setup.side, h_centre=h, h_edge=h, refine_radius=radius, centre=(0.0, 0.0),
                    grading=1.0, rotation=rotation)
    return load_mesh(spec, comm)[0]


def _inside(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(n_points, n_cells) whether each point lies in each convex quadrilateral (corners in
    perimeter order, either orientation), edges included."""
    p = points[:, None, None, :]
    c = corners[None]
    e = np.roll(c, -1, axis=2) - c
    cross = e[..., 0] * (p[..., 1] - c[..., 1]) - e[..., 1] * (p[..., 0] - c[..., 0])
    return np.all(cross >= 0, axis=2) | np.all(cross <= 0, axis=2)


def slit_cells(corners: np.ndarray, setup: TearSetup) -> np.ndarray:
    """Indices of the cells (reference corners (n, 4, 2), perimeter order) that the slit
    crosses: those holding a point of it, sampled at a hundredth of the smallest cell, and the
    cells that cut the warp's bridges across them (:mod:`~fabric_fenicsx.fem.crack_bridges`: where
    two of them meet at a corner only, the warp through it is not cut otherwise). The slit
    lies a millionth of the panel off x = 0 so that it never runs along a column of edges, and
    ends a millionth short of its tip so that a tip on a row of edges takes no cell beyond."""
    y0, y1 = setup.slit_ends
    edge = np.linalg.norm(np.roll(corners, -1, axis=1) - corners, axis=2).min()
    y1 -= 1e-6 * setup.side                   # a tip on a row of edges takes no cell beyond it
    ys = np.linspace(y0, y1, max(2, int(math.ceil((y1 - y0) / (0.01 * edge))) + 1))
    points = np.column_stack((np.full(ys.size, 1e-6 * setup.side), ys))
    hit = np.zeros(corners.shape[0], dtype=bool)
    for chunk in np.array_split(np.arange(points.shape[0]), max(1, points.shape[0] // 200)):
        hit |= _inside(points[chunk], corners).any(axis=0)
    bridges, _ = bridge_cells(corners, corner_nodes(corners), hit, (1.0, 0.0))
    hit[bridges] = True
    return np.flatnonzero(hit)


SECTION_MARGIN = 0.005
"""How far (m) the cells of the uncut section (:func:`section_cells`) lie from the slit's tip and
from the clamped edges."""


def section_cells(centres: np.ndarray, setup: TearSetup) -> np.ndarray:
    """The cells of the uncut section that the tip's strain is compared with
    (:func:`tip_concentration`): centres at least :data:`SECTION_MARGIN` beyond the slit's tip
    across the load (past both tips for a centre notch) and from the clamped edges."""
    y1 = setup.slit_ends[1]
    y = setup.across(centres[:, 1])
    far = (y >= y1 + SECTION_MARGIN) & (np.abs(centres[:, 0]) <= setup.side / 2 - SECTION_MARGIN)
    return np.flatnonzero(far)


def cut_yarn_cells(centres: np.ndarray, setup: TearSetup, h: float) -> np.ndarray:
    """The cells on the slit's cut yarns, away from the slit: centres within the slit's span across
    the load, at least ``h`` inside its tip (tips), and at least :data:`SECTION_MARGIN` from the
    slit's line and from the clamped edges along the load. In the thesis's membrane, whose yarns
    pass no load to each other (Sec. 2.1), a cut yarn carries nothing from the cut to the clamp;
    what these cells' warp strain shows is load the mesh's cells pass into the cut yarns
    (:meth:`TearTest.pull`'s ``cut_strain``)."""
    inside = setup.across(centres[:, 1]) <= setup.slit_ends[1] - h
    along = np.abs(centres[:, 0])
    return np.flatnonzero(inside & (along >= SECTION_MARGIN) & (along <= setup.side / 2 - SECTION_MARGIN))


def near_tip_cells(centres: np.ndarray, slit: np.ndarray, setup: TearSetup, h: float) -> np.ndarray:
    """The cells beyond the slit's tip (centre past it across the load, past either tip for a
    centre notch) within max(:data:`SECTION_MARGIN`, 3 h) of it: where a tear from the slit has
    its first cell (a cell the tear's length counts)."""
    y1 = setup.slit_ends[1]
    y = setup.across(centres[:, 1])
    near = (y > y1) & (np.hypot(centres[:, 0], y - y1) <= max(SECTION_MARGIN, 3.0 * h))
    return np.setdiff1d(np.flatnonzero(near), slit)


def tip_concentration(forces: np.ndarray, tip_strains: np.ndarray, section_strains: np.ndarray,
                      tear_load: float, first: np.ndarray) -> float:
    """The strain concentration of the slit's tip as the mesh resolves it: the warp strain of the
    tear's first cell (``first``, columns of ``tip_strains``) over the mean warp strain of the
    uncut section (``section_strains``), at the sample before the tear whose end force
    (``forces``) is nearest half the tear load (the largest over the first cells if several broke
    in one sample). Rows are samples before the tear. The thesis's membrane carries load only
    along its yarns (Sec. 2.1): every uncut yarn carries the net section's strain and a slit's tip
    concentrates nothing (1.0); what lies above 1 the cells add by coupling neighbouring yarns,
    which depends on the tip cell's shape and orientation (docs/tear_test.md). NaN without a
    tear or without samples before it."""
    forces = np.asarray(forces, float)
    if not (math.isfinite(tear_load) and forces.size and len(first)):
        return math.nan
    k = int(np.argmin(np.abs(forces - 0.5 * tear_load)))
    return float(np.max(np.asarray(tip_strains)[k, first]) / section_strains[k])


def path_angle(centres: np.ndarray) -> tuple[float, float]:
    """(angle from x in degrees, in [0, 180); spread across the path, m) of the principal
    direction of the broken cells' centres ``centres`` (n, 2): the line a tear runs along.
    NaN for fewer than two cells."""
    if centres.shape[0] < 2:
        return math.nan, math.nan
    d = centres - centres.mean(axis=0)
    w, v = np.linalg.eigh(d.T @ d / centres.shape[0])
    direction = v[:, 1]
    return float(math.degrees(math.atan2(direction[1], direction[0])) % 180.0), float(math.sqrt(max(w[0], 0.0)))


def yarn_deviation(angle: float) -> float:
    """Degrees between a direction ``angle`` (from x, the warp) and the nearest yarn."""
    r = angle % 90.0
    return min(r, 90.0 - r)


def work_per_length(length: np.ndarray, energy: np.ndarray) -> float:
    """The energy given up while the tear grew, per unit of its length (J/m): the energy's rise
    from the sample before the tear first grew to the sample where it last grew, over its
    length then (its advance across the load, not the length of a path that zig-zags). Energy
    given up after the tear stopped (a clamp failing) is not counted; NaN if it never grew."""
    length, energy = np.asarray(length, float), np.asarray(energy, float)
    grown = np.flatnonzero(length > 0.0)
    if grown.size == 0:
        return math.nan
    start = energy[grown[0] - 1] if grown[0] > 0 else 0.0
    last = int(np.flatnonzero(np.diff(length, prepend=0.0) > 0.0)[-1])
    return float((energy[last] - start) / length[last])


class TearTest:
    """A panel of ``fabric`` on one mesh (``family``, cell size ``h``), pulled by :meth:`pull`
    (once per strength-scatter seed if wanted: each pull starts from the reference state). One
    rank only (the tear is traced from cell to cell)."""

    def __init__(self, fabric, family: str, h: float, setup: TearSetup = TearSetup(), comm=None,
                 mesh_file: str | None = None):
        from mpi4py import MPI

        from fabric_fenicsx.fem.membrane import Membrane
        from fabric_fenicsx.fem.terms import HourglassControl
        from fabric_fenicsx.fem.timestep import damping_coefficient, unit_cell_frequency
        from fabric_fenicsx.fem.yarn_stress import straight_yarn_modulus
        from fabric_fenicsx.impact.output import cell_corners

        self.comm = comm or MPI.COMM_WORLD
        if self.comm.size > 1:
            raise ValueError("the tear test runs on one rank (its tear is traced cell to cell); run it without mpirun")
        self.fabric, self.family, self.h, self.setup = fabric, family, float(h), setup
        self.msh = panel_mesh(family, h, setup, self.comm, mesh_file)
        self.membrane = m = Membrane(self.msh, angle=0.0, quadrature_degree=1)
        self.k_straight = straight_yarn_modulus(fabric)
        m.add_term(HourglassControl(setup.hourglass, self.k_straight))
        self.beta = damping_coefficient(setup.damping, unit_cell_frequency(fabric, self.k_straight))
        a, tol = setup.side / 2, 1e-9 * setup.side
        self.fixed = m.boundary_dofs(lambda x: np.abs(x[0] + a) < tol)
        self.pulled = m.boundary_dofs(lambda x: np.abs(x[0] - a) < tol)
        n = m.n_owned_dofs
        self.fixed_x = self.fixed[(self.fixed % 3 == 0) & (self.fixed < n)]
        self.pulled_x = self.pulled[(self.pulled % 3 == 0) & (self.pulled < n)]
        if setup.grips == "rollers":    # the edges slide along y: only x (and z) held, y at one corner
            held = np.concatenate([self.fixed, self.pulled])
            corner = self.fixed[self.fixed % 3 == 1][:1]
            self.held = np.concatenate([held[held % 3 != 1], corner])
        else:
            self.held = np.concatenate([self.fixed, self.pulled])
        X = m.V.tabulate_dof_coordinates()[:, :2]
        self.corners = X[cell_corners(m.V, m.n_cells)]
        self.centres = self.corners.mean(axis=1)
        self.slit = slit_cells(self.corners, setup)
        self.n_cells = self.comm.allreduce(m.n_cells)
        self.cell_size = float(self.comm.allreduce(
            float(np.min(np.linalg.norm(np.diff(self.corners, axis=1, append=self.corners[:, :1]), axis=-1),
                         initial=np.inf)), op=MPI.MIN))
        from scipy.sparse import csr_matrix

        nodes = cell_corners(m.V, m.n_cells)
        incidence = csr_matrix((np.ones(nodes.size), (np.repeat(np.arange(m.n_cells), 4), nodes.ravel())))
        self._adjacent = (incidence @ incidence.T).tocsr()      # cells that share a node
        self.near_tip = near_tip_cells(self.centres, self.slit, setup, self.h)
        """The cells about the slit's tip, beyond it: the tear's first cells are among them."""
        self.section = section_cells(self.centres, setup)
        self.cut_yarns = cut_yarn_cells(self.centres, setup, self.h)
        """The cells on the slit's cut yarns, away from it (:func:`cut_yarn_cells`)."""

    def _yarn_average(self):
        """The driving strains of the yarn-average rule on this mesh (built once)."""
        if getattr(self, "_average", None) is None:
            from fabric_fenicsx.fem.yarn_average import YarnAverage
            from fabric_fenicsx.fem.polygons import polygon_areas

            self._average = YarnAverage(self.centres, polygon_areas(self.corners), (np.array([1.0, 0.0]), np.array([0.0, 1.0])),
                                        self.setup.failure_length, self.comm, self.setup.failure_width)
        return self._average

    def crack_rule(self, laws=None):
        """The crack-tracking rule of this setup (:data:`~fabric_fenicsx.fem.crack_rules.CRACK_RULES`) on
        this mesh with the cell laws ``laws`` (None: the fabric's), the slit given as a crack of
        the warp."""
        rule = crack_rule_on_cells(self.setup.failure, self.corners, (np.array([1.0, 0.0]), np.array([0.0, 1.0])),
                                   self.fabric, self.membrane.n_points_per_cell, laws, self.comm)
        rule.add_crack(self.slit, 0, 0.0)
        return rule

    def damage_range(self, laws=None):
        """The damage range (:class:`~fabric_fenicsx.material.scatter.DamageRange`) the surrogate
        needs for this setup's failure rule with ``laws``, or None (the fabric's own law)."""
        if self.setup.failure in CRACK_RULES:
            return self.crack_rule(laws).damage_range()
        if laws is None:
            return None
        from fabric_fenicsx.material.scatter import DamageRange

        return DamageRange.of_laws(self.fabric, *laws)

    def laws(self, scatter):
        """The cell laws (mu_crit, scale), each (n_points, 2), of ``scatter`` on this mesh."""
        from fabric_fenicsx.material.scatter import cell_laws

        return cell_laws(scatter, self.fabric, 0.0, self.corners)

    def tear_cells(self, broken: np.ndarray) -> np.ndarray:
        """The cells of the tear: the broken cells (``broken``, a mask) joined to the slit through
        broken cells sharing a node (damage elsewhere, at a clamp, is not the tear)."""
        from scipy.sparse.csgraph import connected_components

        keep = np.flatnonzero(broken | np.isin(np.arange(broken.size), self.slit))
        _, label = connected_components(self._adjacent[keep][:, keep], directed=False)
        torn = np.isin(label, label[np.isin(keep, self.slit)])
        cells = keep[torn]
        return cells[~np.isin(cells, self.slit)]

    def tear_length(self, cells: np.ndarray) -> float:
        """How far the tear ``cells`` has run across the load beyond the slit's tip (m)."""
        y1 = self.setup.slit_ends[1]
        return max(0.0, float(np.max(self.setup.across(self.centres[cells, 1]), initial=-np.inf)) - y1)

    def crack_away(self, rule, t: float, length: float) -> dict | None:
        """The first crack that the yarn-crack ``rule`` started of its own (a root) away from the
        slit's line: where, when and how far the tear had run, or None. This membrane carries load
        only along its yarns, so the tear's tip does not concentrate the strain: a yarn may break
        wherever the cells' strain is highest along it, at a clamp as well (docs/tear_test.md)."""
        from fabric_fenicsx.fem.yarn_crack import ROOT

        family, cells = np.nonzero(rule.kind == ROOT)
        if cells.size == 0:
            return None
        k = int(np.argmin(np.abs(self.centres[cells, 0])))
        return {"family": ("warp", "fill")[family[k]], "x": float(self.centres[cells[k], 0]),
                "y": float(self.centres[cells[k], 1]), "t": float(t), "tear_length": float(length)}

    def pull(self, surrogate, laws=None, progress=None, twin: int = 0) -> dict:
        """Pull the panel with the cell laws ``laws`` (None: the fabric's own law), at the speed
        changed by ``twin`` x 1e-12 of itself (a round-off twin: after damage a pull is a draw, as
        an impact run is, docs/tear_test.md), until the tear has run through, the force has
        fallen below a tenth of its peak, or the right edge has moved three times the warp's
        failure strain. Returns the measures of the module
        docstring, the sampled history (``history``: t, force, tear length, energy) and the
        final cells (``cells``: corners, warp alpha, the warp's damage dissipation per cell in J,
        removed, slit, tear) for pictures."""
        from fabric_fenicsx.fem.explicit import CentralDifference
        from fabric_fenicsx.fem.yarn_stress import YarnStress
        from fabric_fenicsx.impact.removal import CellRemoval

        t0 = time.perf_counter()
        m, s = self.membrane, self.setup
        m.restart()                  # every pull starts intact, from the reference state
        material = YarnStress(surrogate, m.quadrature_weights_detJ, True, self.beta,
                              straight_modulus=self.k_straight, laws=laws)
        if s.failure == "yarn_average":
            material.damage_drive = self._yarn_average()
        rule = None
        if s.failure in CRACK_RULES:
            material.failure = rule = self.crack_rule(laws)
        for term in m.terms:
            if term.follows_integrity:
                term.follow(lambda: material.state, material.tension)
        removal = CellRemoval(m, material, np.zeros(0, dtype=np.int64), s.erosion_strain)
        if s.slit_cut == "warp":   # the slit's cells keep their fill yarns: a crack band of cut warp
            material.alpha1[(self.slit[:, None] * m.n_points_per_cell + np.arange(m.n_points_per_cell)).ravel()] = 0.0
        else:
            removal.remove(self.slit, np.zeros(0, dtype=np.int64))
        removal.deleted_cells[:] = False          # the slit is not a failure
        m.share_live_cells()
        cd = CentralDifference(m, material, self.fabric.areal_density,
                               self.held, cell_size=self.cell_size,
                               safety=s.dt_safety)
        cd.v[self.pulled_x] = s.speed * (1.0 + twin * 1e-12)
        dt = cd.stable_dt()
        E_fail = surrogate.E_fail[0]
        t_max = 3.0 * (math.sqrt(1 + 2 * E_fail) - 1.0) * s.side / s.speed
        npc = m.n_points_per_cell
        history, peak, first, elsewhere = [], 0.0, None, None
        tip_samples, concentration = [], math.nan    # (force, near-tip cells' and section's warp strains)
        tear_strain = cut_strain = math.nan
        end = "time limit"
        while cd.time < t_max:
            cd.step(dt)
            delete, erode = removal.select()
            if delete.size + erode.size:
                removal.remove(delete, erode)
                m.share_live_cells()
            if cd.n_steps % 10:
                continue
            dt = cd.stable_dt()
            force = -float(np.sum(cd._f_int[self.fixed_x]))
            if not math.isfinite(force):
                raise FloatingPointError(
                    f"tear test, {self.family} {self.h * 1e3:g} mm: the end force is {force} at t = "
                    f"{cd.time * 1e6:.2f} us (step {cd.n_steps}, dt {dt:.3e} s); lower dt_safety "
                    f"({s.dt_safety}) or raise the hourglass control ({s.hourglass})")
            broken = (material.alpha1.reshape(-1, npc).min(axis=1) < BROKEN_ALPHA) | ~removal.live_cells
            torn = self.tear_cells(broken)
            length = self.tear_length(torn)
            if first is None:
                warp = material.E1.reshape(-1, npc).mean(axis=1)
                intact = self.section[~broken[self.section]]   # a crack elsewhere is not the section
                section_strain = warp[intact].mean() if intact.size else math.nan
            if first is None and length > 0.0:
                f, b, sec = (np.array(x) for x in zip(*tip_samples)) if tip_samples else ([], [], [])
                concentration = tip_concentration(f, b, sec, force, np.flatnonzero(np.isin(self.near_tip, torn)))
                tear_strain = float(section_strain)
                cut_strain = float(warp[self.cut_yarns].mean() / section_strain) if self.cut_yarns.size else math.nan
            elif first is None:
                tip_samples.append((force, warp[self.near_tip], section_strain))
            e = material.energies()
            history.append((cd.time, force, length, e["damage_dissipation"] + e["erosion_energy"]))
            peak = max(peak, force)
            if first is None and length > 0.0:
                first = force
            if rule is not None and elsewhere is None:
                elsewhere = self.crack_away(rule, cd.time, length)
            if progress is not None and cd.n_steps % 2000 == 0:
                progress(f"t = {cd.time * 1e3:.3f} ms, force {force:.1f} N, tear {length * 1e3:.1f} mm")
            if length >= s.ligament - 1.5 * self.h:
                end = "torn through"
                break
            if first is not None and force < 0.1 * peak:
                end = "force fell below a tenth of its peak"
                break
        if elsewhere is not None:
            end += (f"; a crack of the {elsewhere['family']} started away from the tear at "
                    f"({elsewhere['x'] * 1e3:.1f}, {elsewhere['y'] * 1e3:.1f}) mm, t = {elsewhere['t'] * 1e3:.3f} ms, "
                    f"with the tear at {elsewhere['tear_length'] * 1e3:.1f} mm")
        hist = np.array(history).reshape(-1, 4)
        broken_final = (material.alpha1.reshape(-1, npc).min(axis=1) < BROKEN_ALPHA) | ~removal.live_cells
        tear_cells = self.tear_cells(broken_final)
        angle, spread = path_angle(self.centres[tear_cells])
        e = material.energies()
        return {"family": self.family, "h": self.h, "n_cells": self.n_cells, "notch": s.notch,
                "tear_load": first if first is not None else math.nan, "peak_force": peak,
                "work_per_length": work_per_length(hist[:, 2], hist[:, 3]),
                "tear_length": float(hist[-1, 2]) if hist.size else 0.0,
                "path_angle": angle, "path_deviation": yarn_deviation(angle) if math.isfinite(angle) else math.nan,
                "path_spread": spread, "tip_concentration": concentration, "tear_strain": tear_strain,
                "cut_strain": cut_strain, "n_tear_cells": int(tear_cells.size),
                "deleted": int(removal.deleted_cells.sum()), "eroded": int(removal.eroded_cells.sum()),
                "damage_dissipation": e["damage_dissipation"], "erosion_energy": e["erosion_energy"],
                "viscous_dissipation": e["viscous_dissipation"], "end": end, "steps": cd.n_steps,
                "seconds": time.perf_counter() - t0, "history": hist, "crack_away": elsewhere,
                "cells": {"corners": self.corners, "alpha1": material.alpha1.reshape(-1, npc).min(axis=1),
                          "warp_dissipation": material.point_dissipation[0].reshape(-1, npc).sum(axis=1),
                          "removed": ~removal.live_cells, "slit": np.isin(np.arange(m.n_cells), self.slit),
                          "tear": np.isin(np.arange(m.n_cells), tear_cells)}}


def setup_dict(setup: TearSetup) -> dict:
    """The setup as a plain dict (for the report)."""
    return asdict(setup)
