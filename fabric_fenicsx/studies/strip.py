"""The strip test of the strength scatter: a fabric strip pulled along the warp to failure.

A strip (default 50 x 10 mm, warp along its length) is clamped at both ends; the far end moves
at a constant speed (default 5 m/s: a strain rate of 100 /s, the waves cross the strip tens of
times before the peak; measured on 2 mm cells, 2 m/s gives the strip without scatter 1.2 %
more strength and four seeds 1.2-3.6 % less: close to, not at, the quasi-static limit). The membrane, the
reduced element with its hourglass control, the surrogate and the damping are the impact
scenes' (``run.damping`` 0.1 of critical at the unit cell). The strip's strength is its largest
end force (N), read from the internal force at the fixed end. A run ends once the force has
fallen below half its peak.

With a strength scatter (:mod:`fabric_fenicsx.material.scatter`) each seed is another fabric,
and the strengths of many seeds are the strip's strength distribution. The study runs them on
two mesh sizes and two mesh families (``aligned``: a grid along the yarns; ``free``: gmsh's
unstructured quadrilaterals) and compares the distributions: whether the rule by which a cell
reads the field (:func:`~fabric_fenicsx.material.scatter.cell_laws`) makes the failure
statistics independent of the cell size. The failure rule is the thesis's (each point's own law)
or a crack-tracking one (``failure``: a name of :data:`~fabric_fenicsx.fem.crack_rules.CRACK_RULES`,
the scenes' ``material.failure``). The first break is the weakest segment under either rule;
what follows it is the rule's. Under the thesis's rule the tear runs across at once (the weakest
link). Under ``del_zone_budget`` it grows tip by tip, against the cells' own laws, so that its
strips are stronger the smaller the cells (docs/mesh_independence.md, section 10.1).
``fabric-fenicsx study strip`` is its command line; it writes strip-<family>-<size>.csv (a row
per seed as it ends), strip.json and strip.png.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["StripSetup", "strip_mesh", "StripTest", "weibull_fit", "compare", "paired", "against"]


@dataclass(frozen=True)
class StripSetup:
    """Geometry and loading of a strip test (SI units)."""

    length: float = 0.05
    width: float = 0.01
    speed: float = 5.0
    damping: float = 0.1
    hourglass: float = 0.05
    dt_safety: float = 0.8
    cell_rule: str = "weakest"   # how a cell reads the segments (material.scatter.cell_laws)
    crack_band: bool = False     # softening scales x l / h (l = a warp segment, h = the cell's length)
    shear_modulus: float = 0.0  # N/m: isotropic in-plane shear (membrane.shear_modulus), 0 = the thesis's
    t_max: float = 0.0          # 0: until the strain reaches twice the warp's failure strain
    failure: str = "thesis"     # "thesis" (each point's own law) or one of fem.crack_rules.CRACK_RULES

    def __post_init__(self):
        from fabric_fenicsx.fem.crack_rules import CRACK_RULES

        if self.failure != "thesis" and self.failure not in CRACK_RULES:
            raise ValueError(f"failure = {self.failure!r}: must be thesis or one of {', '.join(CRACK_RULES)}")


def strip_mesh(family: str, h: float, setup: StripSetup, comm):
    """Quadrilateral mesh of the strip [0, length] x [-width/2, width/2] with cells of about
    ``h``: ``aligned`` (a grid along x and y) or ``free`` (gmsh, Frontal-Delaunay with blossom
    recombination, the impact scenes' graded family's mesher)."""
    import dolfinx.mesh

    L, W = setup.length, setup.width
    if family == "aligned":
        nx, ny = max(1, round(L / h)), max(1, round(W / h))
        return dolfinx.mesh.create_rectangle(comm, [np.array([0.0, -W / 2]), np.array([L, W / 2])],
                                             [nx, ny], cell_type=dolfinx.mesh.CellType.quadrilateral)
    if family != "free":
        raise ValueError(f"mesh family must be 'aligned' or 'free', got {family!r}")
    from fabric_fenicsx.fem.mesh_file import free_rectangle

    return free_rectangle((0.0, -W / 2), (L, W / 2), h, comm)


class StripTest:
    """A strip of ``fabric`` on one mesh, pulled once per scatter seed (:meth:`pull`).

    The mesh, membrane and forms are built once; each pull starts from the reference state with
    the seed's cell laws. ``surrogate``: the table, built by the caller with a ``damage_range``
    that holds every seed's laws (:meth:`laws` gives them before any pull)."""

    def __init__(self, fabric, family: str, h: float, setup: StripSetup = StripSetup(), comm=None):
        from mpi4py import MPI

        from fabric_fenicsx.fem.membrane import Membrane
        from fabric_fenicsx.fem.terms import HourglassControl, IsotropicShear
        from fabric_fenicsx.fem.timestep import damping_coefficient, unit_cell_frequency
        from fabric_fenicsx.fem.yarn_stress import straight_yarn_modulus
        from fabric_fenicsx.impact.output import cell_corners

        self.comm = comm or MPI.COMM_WORLD
        self.fabric, self.family, self.h, self.setup = fabric, family, float(h), setup
        self.msh = strip_mesh(family, h, setup, self.comm)
        self.membrane = m = Membrane(self.msh, angle=0.0, quadrature_degree=1)
        self.k_straight = straight_yarn_modulus(fabric)
        m.add_term(HourglassControl(setup.hourglass, self.k_straight))
        if setup.shear_modulus > 0:
            m.add_term(IsotropicShear(setup.shear_modulus))
        self.beta = damping_coefficient(setup.damping, unit_cell_frequency(fabric, self.k_straight))
        L = setup.length
        tol = 1e-9 * L
        self.fixed = m.boundary_dofs(lambda x: np.abs(x[0]) < tol)
        self.pulled = m.boundary_dofs(lambda x: np.abs(x[0] - L) < tol)
        n = m.n_owned_dofs
        self.fixed_x = self.fixed[(self.fixed % 3 == 0) & (self.fixed < n)]
        self.pulled_x = self.pulled[(self.pulled % 3 == 0) & (self.pulled < n)]
        X = m.V.tabulate_dof_coordinates()[:, :2]
        self.corners = X[cell_corners(m.V, m.n_cells)]
        self.n_cells = self.comm.allreduce(m.n_cells)
        self.cell_size = float(self.comm.allreduce(
            float(np.min(np.linalg.norm(np.diff(self.corners, axis=1, append=self.corners[:, :1]), axis=-1),
                         initial=np.inf)), op=MPI.MIN))

    def _broken(self, material) -> bool:
        """Whether some warp yarn has lost half its fibrils (the force's fall is a failure,
        not the crimp's slack)."""
        from mpi4py import MPI

        a1 = material.alpha1
        return self.comm.allreduce(float(a1.min(initial=1.0)), op=MPI.MIN) < 0.5

    def laws(self, scatter):
        """The cell laws (mu_crit, scale), each (n_points, 2), of ``scatter`` on this mesh."""
        from fabric_fenicsx.material.scatter import cell_laws

        mu_crit, scale = cell_laws(scatter, self.fabric, 0.0, self.corners, rule=self.setup.cell_rule)
        if self.setup.crack_band:   # the softening of a cell of length h spread as over one segment
            length = np.ptp(self.corners[:, :, 0], axis=1)          # along the warp (x)
            scale = scale * np.minimum(1.0, 2.0 * self.fabric.warp.w / length)[:, None]
        return mu_crit, scale

    def crack_rule(self, laws=None):
        """The crack-tracking rule of this setup (``failure``) on this strip's cells with the cell
        laws ``laws`` (None: the fabric's), or None for the thesis's rule."""
        if self.setup.failure == "thesis":
            return None
        from fabric_fenicsx.fem.crack_rules import crack_rule_on_cells

        return crack_rule_on_cells(self.setup.failure, self.corners, (np.array([1.0, 0.0]), np.array([0.0, 1.0])),
                                   self.fabric, self.membrane.n_points_per_cell, laws, self.comm)

    def damage_range(self, scatter, laws):
        """The damage range (:class:`~fabric_fenicsx.material.scatter.DamageRange`) a pull with the
        cell laws ``laws`` of ``scatter`` (None: the fabric's own law) needs of the surrogate's
        table, the failure rule's included; None: the fabric's own range."""
        from fabric_fenicsx.material.scatter import DamageRange

        own = scatter.damage_range(self.fabric, *laws) if laws is not None else None
        rule = self.crack_rule(laws)
        return DamageRange.union(rule.damage_range(), own) if rule is not None else own

    def pull(self, surrogate, laws=None) -> dict:
        """Pull the strip with the cell laws ``laws`` (None: the fabric's own law) to failure:
        {"peak_force" (N), "strain_at_peak" (end displacement / length), "steps", "seconds",
        "damage_dissipation" (J), "viscous_dissipation" (J)}."""
        from mpi4py import MPI

        from fabric_fenicsx.fem.explicit import CentralDifference
        from fabric_fenicsx.fem.yarn_stress import YarnStress

        t0 = time.perf_counter()
        m, s = self.membrane, self.setup
        m.restart()                  # every pull starts intact, from the reference state
        material = YarnStress(surrogate, m.quadrature_weights_detJ, True, self.beta,
                              straight_modulus=self.k_straight, laws=laws)
        rule = self.crack_rule(laws)
        if rule is not None:
            material.failure = rule
        for term in m.terms:
            if term.follows_integrity:
                term.follow(lambda: material.state, material.tension)
        cd = CentralDifference(m, material, self.fabric.areal_density,
                               np.concatenate([self.fixed, self.pulled]), cell_size=self.cell_size,
                               safety=s.dt_safety)
        cd.v[self.pulled_x] = s.speed
        dt = cd.stable_dt()
        E_fail = surrogate.E_fail[0]
        t_max = s.t_max or 2.0 * (math.sqrt(1 + 2 * E_fail) - 1.0) * s.length / s.speed
        peak, peak_strain, force = 0.0, 0.0, 0.0
        while cd.time < t_max:
            if rule is not None:
                rule.time = cd.time
            cd.step(dt)
            if cd.n_steps % 10 == 0:
                dt = cd.stable_dt()
            force = -self.comm.allreduce(float(np.sum(cd._f_int[self.fixed_x])), op=MPI.SUM)
            if force > peak:
                peak, peak_strain = force, cd.time * s.speed / s.length
            elif force < 0.5 * peak and self._broken(material):
                break
        energies = {k: self.comm.allreduce(v, op=MPI.SUM) for k, v in material.energies().items()}
        return {"peak_force": peak, "strain_at_peak": peak_strain, "steps": cd.n_steps,
                "seconds": time.perf_counter() - t0, "end_force": force,
                "damage_dissipation": energies["damage_dissipation"],
                "viscous_dissipation": energies["viscous_dissipation"]}


def weibull_fit(values) -> tuple[float, float]:
    """(modulus m, scale) of a two-parameter Weibull distribution fitted to ``values`` by
    maximum likelihood (scipy.stats.weibull_min with the location fixed at 0)."""
    from scipy.stats import weibull_min

    x = np.asarray(values, float)
    m, _, scale = weibull_min.fit(x, floc=0.0)
    return float(m), float(scale)


def compare(a, b) -> dict:
    """Two samples of strip strengths: their means and 95 % intervals (Student t), the
    difference of the means with its 95 % interval (Welch), Welch's and the two-sample
    Kolmogorov-Smirnov test's p-values."""
    from scipy import stats

    a, b = np.asarray(a, float), np.asarray(b, float)
    out = {}
    for name, x in (("a", a), ("b", b)):
        out[f"mean_{name}"] = float(x.mean())
        out[f"ci95_{name}"] = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    va, vb = a.var(ddof=1) / a.size, b.var(ddof=1) / b.size
    dof = (va + vb) ** 2 / (va ** 2 / (a.size - 1) + vb ** 2 / (b.size - 1)) if va + vb > 0 else 1.0
    out["difference"] = float(a.mean() - b.mean())
    out["difference_ci95"] = float(stats.t.ppf(0.975, dof) * math.sqrt(va + vb))
    out["welch_p"] = float(stats.ttest_ind(a, b, equal_var=False).pvalue) if va + vb > 0 else 1.0
    out["ks_p"] = float(stats.ks_2samp(a, b).pvalue)
    return out


def paired(a: dict, b: dict) -> dict:
    """Two studies' tables of one mesh ({seed: row}, :func:`read_table`) compared fabric by
    fabric over the seeds both pulled (the scattered ones, seed >= 0): ``n``, the mean of the
    strength differences a - b with its 95 % interval (Student t over the pairs), their sd and the
    two samples' correlation (:func:`~fabric_fenicsx.studies.means.paired`); and :func:`compare`
    of the same seeds unpaired (``unpaired``)."""
    from fabric_fenicsx.studies.means import paired as member_by_member

    seeds = sorted(s for s in set(a) & set(b) if s >= 0)
    x = np.array([a[s]["peak_force"] for s in seeds])
    y = np.array([b[s]["peak_force"] for s in seeds])
    return {**member_by_member(x, y), "unpaired": compare(x, y)}


def against(tables: dict, others: dict) -> dict:
    """Every mesh of two studies ({(family, h): {seed: row}} each) that both pulled, compared seed
    by seed (:func:`paired`), by the mesh's name (``aligned 2 mm``)."""
    return {f"{family} {h * 1e3:g} mm": paired(tables[(family, h)], others[(family, h)])
            for family, h in sorted(set(tables) & set(others))}


def format_against(report: dict, label: str) -> str:
    """:func:`against`'s report as a line per mesh (this study - ``label``)."""
    lines = []
    for name, c in report.items():
        u = c["unpaired"]
        lines.append(f"{name}, this - {label}, {c['n']} fabrics: paired {c['mean_difference']:+.1f} +- "
                     f"{c['difference_ci95']:.1f} N (sd {c['sd_difference']:.1f} N, correlation "
                     f"{c['correlation']:.3f}); means {u['mean_a']:.1f} +- {u['ci95_a']:.1f} against "
                     f"{u['mean_b']:.1f} +- {u['ci95_b']:.1f} N, Welch p = {u['welch_p']:.3f}, KS p = {u['ks_p']:.3f}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- the study
COLUMNS = ("seed", "peak_force", "strain_at_peak", "steps", "seconds", "damage_dissipation",
           "viscous_dissipation")


def run_configuration(family: str, h: float, model: str, seeds: list[int], path: str,
                      setup: StripSetup = StripSetup()) -> str:
    """Pull the strip on one mesh (``family``, cell size ``h``) once with scatter "none" (seed
    -1 in the table) and once per seed of ``model``, appending a row per pull to the CSV
    ``path`` as it ends; seeds already in it are not pulled again (an interrupted study
    resumes). Returns ``path``."""
    import csv
    from pathlib import Path

    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.material.scatter import DamageRange, StrengthScatter
    from fabric_fenicsx.surrogate.table import Surrogate

    path = Path(path)
    done = set()
    if path.exists():
        with open(path) as f:
            done = {int(r["seed"]) for r in csv.DictReader(f)}
    else:
        with open(path, "w", newline="") as f:
            csv.writer(f).writerow(COLUMNS)
    fabric = zylon_as()
    test = StripTest(fabric, family, h, setup)
    todo = [s for s in [-1, *seeds] if s not in done]
    laws = {s: (None if s < 0 else test.laws(StrengthScatter(model, seed=s))) for s in todo}
    damage_range = DamageRange.union(*(test.damage_range(StrengthScatter(model), law) for law in laws.values()))
    surrogate = Surrogate(fabric, progress=False, workers=1, damage_range=damage_range)
    for seed in todo:
        r = test.pull(surrogate, laws[seed])
        with open(path, "a", newline="") as f:
            csv.writer(f).writerow([seed, *(f"{r[c]:.10g}" for c in COLUMNS[1:])])
    return str(path)


def read_table(path) -> dict:
    """{seed: row} of a configuration's CSV (numbers as floats)."""
    import csv

    with open(path) as f:
        return {int(r["seed"]): {k: float(v) for k, v in r.items() if k != "seed"} for r in csv.DictReader(f)}


def summarise(tables: dict) -> dict:
    """The study's report from {(family, h): {seed: row}}: per mesh the deterministic strength,
    the scattered strengths' mean, 95 % interval, sd and Weibull fit; and every pair of meshes
    compared (:func:`compare`)."""
    meshes, strengths = {}, {}
    for (family, h), rows in sorted(tables.items()):
        name = f"{family} {h * 1e3:g} mm"
        x = np.array([r["peak_force"] for s, r in sorted(rows.items()) if s >= 0])
        strengths[name] = x
        entry = {"family": family, "h": h, "deterministic": rows.get(-1, {}).get("peak_force"),
                 "n": int(x.size)}
        if x.size > 2:
            m, scale = weibull_fit(x)
            entry.update(mean=float(x.mean()), sd=float(x.std(ddof=1)),
                         ci95=compare(x, x)["ci95_a"], weibull_modulus=m, weibull_scale=scale,
                         seconds_per_pull=float(np.mean([r["seconds"] for s, r in rows.items() if s >= 0])))
        meshes[name] = entry
    names = [n for n in strengths if strengths[n].size > 2]
    pairs = {f"{a} | {b}": compare(strengths[a], strengths[b])
             for i, a in enumerate(names) for b in names[i + 1:]}
    return {"meshes": meshes, "pairs": pairs}


def plot(tables: dict, report: dict, path) -> None:
    """Empirical distribution of the strip strength per mesh, with its Weibull fit."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from scipy.stats import weibull_min

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (family, h), rows in sorted(tables.items()):
        name = f"{family} {h * 1e3:g} mm"
        x = np.sort([r["peak_force"] for s, r in rows.items() if s >= 0])
        if x.size < 3:
            continue
        p = (np.arange(1, x.size + 1) - 0.5) / x.size
        line, = ax.step(x, p, where="mid", label=f"{name}: {x.size} seeds")
        e = report["meshes"][name]
        grid = np.linspace(x[0], x[-1], 200)
        ax.plot(grid, weibull_min.cdf(grid, e["weibull_modulus"], scale=e["weibull_scale"]), ":",
                color=line.get_color())
        if e.get("deterministic"):
            ax.axvline(e["deterministic"], color=line.get_color(), lw=0.8, ls="--")
    ax.set(xlabel="strip strength: peak end force (N)", ylabel="fraction of seeds below")
    rule = report.get("setup", {}).get("failure", "thesis")
    ax.set_title(f"strip pulled along the warp, failure rule {rule}\n(dotted: Weibull fit; dashed: the strip "
                 "without scatter)", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def format_report(report: dict) -> str:
    """The report as text: a line per mesh and per pair of meshes."""
    lines = [f"{'mesh':<16}{'no scatter (N)':>16}{'seeds':>7}{'mean (N)':>11}{'+- 95 %':>9}{'sd':>8}"
             f"{'Weibull m':>11}{'s/pull':>8}"]
    for name, e in report["meshes"].items():
        det = f"{e['deterministic']:.1f}" if e.get("deterministic") else "-"
        if "mean" in e:
            lines.append(f"{name:<16}{det:>16}{e['n']:>7}{e['mean']:>11.1f}{e['ci95']:>9.1f}{e['sd']:>8.1f}"
                         f"{e['weibull_modulus']:>11.1f}{e['seconds_per_pull']:>8.1f}")
        else:
            lines.append(f"{name:<16}{det:>16}{e['n']:>7}")
    for pair, c in report["pairs"].items():
        lines.append(f"{pair}: difference {c['difference']:+.1f} +- {c['difference_ci95']:.1f} N, "
                     f"Welch p = {c['welch_p']:.3f}, KS p = {c['ks_p']:.3f}")
    return "\n".join(lines)
