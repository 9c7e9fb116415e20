"""Extending the model as a user does: a weak-form term named in a scene file runs from
``fabric-fenicsx impact`` and from a study; a viscous term's work is booked as dissipation and
the stable step respects its viscosity (one rule, :func:`fabric_fenicsx.fem.timestep.stable_dt`);
the step the run reports is the step it uses; a material and a surrogate built elsewhere."""
import json
import math
import textwrap

import numpy as np
import pytest
from mpi4py import MPI

from fabric_fenicsx.fem.timestep import stable_dt
from fabric_fenicsx.fem.yarn_stress import YarnStress
from fabric_fenicsx.impact.scene import SceneError, load_scene
from fabric_fenicsx.impact.simulation import ImpactError, ImpactSimulation
from fabric_fenicsx.material.contract import QuadratureMaterial

serial_only = pytest.mark.skipif(MPI.COMM_WORLD.size > 1, reason="runs its own processes")

VISCOUS_TERM = '''
import ufl
from fabric_fenicsx.fem.terms import MembraneTerm


class Viscous(MembraneTerm):
    """A membrane viscosity eta (N s/m): r = eta Grad(velocity) : Grad v."""
    name = "viscous"
    dissipative = True

    def __init__(self, eta):
        self.eta = float(eta)

    def integrand(self, m):
        return self.eta * ufl.inner(ufl.grad(m.velocity), ufl.grad(m.v))

    def viscosity(self):
        return self.eta
'''

SCENE = '''
description = "tiny elastic impact with a user's viscous term"
[material]
angle = 90.0
damage = false
[mesh]
kind = "uniform"
side = 0.08
n = 12
[projectile]
diameter = 0.02
velocity = 20.0
mass = 0.005
[boundary]
clamped = ["bottom", "top"]
[run]
t_end = {t_end}
[output]
xdmf_interval = 0.0
png = false
progress_interval = 0.0
[membrane]
terms = [{terms}]
'''

ETA = 20.0   # N s/m: the case that blew up when the step ignored a term's damping


def write_scene(folder, eta=ETA, t_end=6e-5, terms=None):
    (folder / "viscous.py").write_text(VISCOUS_TERM)
    if terms is None:
        terms = f'{{class = "viscous.py:Viscous", eta = {eta!r}}}'
    path = folder / "scene.toml"
    path.write_text(SCENE.format(t_end=t_end, terms=terms))
    return path


def test_a_scene_names_a_term_by_file_and_its_arguments_are_checked(tmp_path):
    scene = load_scene(write_scene(tmp_path))
    (spec,) = scene.membrane.terms
    assert spec["eta"] == ETA and spec["class"] == f"{(tmp_path / 'viscous.py').resolve()}:Viscous"
    bad = [('"viscous.py:Nothing"', "has no 'Nothing'"),
           ('"absent.py:Viscous"', "no such file"),
           ('"no_such_module_xyz:Viscous"', "cannot be imported"),
           ('{class = "viscous.py:Viscous", mu = 1.0}', "signature"),
           ('"json:JSONDecoder"', "not a subclass"),
           ('"viscous"', "is not a term")]
    for terms, message in bad:
        with pytest.raises(SceneError, match=message):
            load_scene(write_scene(tmp_path, terms=terms))


@serial_only
def test_a_viscous_term_is_booked_as_dissipation_and_its_step_is_respected(tmp_path):
    scene = load_scene(write_scene(tmp_path))
    sim = ImpactSimulation(scene, tmp_path / "out", verbose=False)
    term = sim.membrane.terms[-1]
    assert term.name == "viscous" and sim.membrane.terms_viscosity() == ETA
    # The run's step is the one rule with the term's viscosity, and much shorter than without it.
    K = sim._material_modulus() + sim.membrane.terms_wave_modulus()
    rule = stable_dt(K, sim.rho_A, sim.L_min, sim.material.beta, scene.run.dt_safety, ETA)
    assert sim.dt == rule == sim.cd.stable_dt()
    undamped = stable_dt(K, sim.rho_A, sim.L_min, sim.material.beta, scene.run.dt_safety)
    assert sim.dt < 0.2 * undamped
    summary = sim.run()
    sim.output.close()
    e = summary["energies"]
    assert summary["end_reason"] == "time_limit" and summary["energy_error"] < 0.01
    assert e["terms_dissipation"] > 0.05 * (e["projectile_kinetic_0"] - e["projectile_kinetic"])
    assert e["elastic_work"] == pytest.approx(e["internal_work"] - e["viscous_dissipation"]
                                              - e["terms_dissipation"], rel=1e-12)
    assert e["stored_energy"] >= 0.0
    # Reported = used: the summary's and the history's steps are the run's.
    assert summary["dt_initial"] == sim.dt_initial == rule
    with open(tmp_path / "out" / "history.csv") as f:
        header = f.readline().strip().split(",")
        first = dict(zip(header, f.readline().strip().split(",")))
    assert float(first["dt"]) == pytest.approx(rule, rel=1e-6)

    # The same run with the viscosity left out of the step blows up: the rule is what keeps it.
    blind = ImpactSimulation(load_scene(write_scene(tmp_path)), tmp_path / "blind", verbose=False)
    blind.membrane.terms[-1].viscosity = lambda: 0.0
    blind.dt = blind.stable_dt(blind._material_modulus())
    assert blind.dt == pytest.approx(undamped, rel=1e-12)
    with pytest.raises(ImpactError, match="step"):
        blind.run()
    blind.output.close()


@serial_only
def test_the_integrator_message_quotes_the_step_the_run_used(tmp_path):
    scene = load_scene(write_scene(tmp_path, terms=""))
    sim = ImpactSimulation(scene, tmp_path / "out", verbose=False)
    sim.cd.step(sim.dt)
    sim.cd.u[:] = np.nan
    with pytest.raises(FloatingPointError) as err:
        sim.cd.step(0.5 * sim.dt)
    text = str(err.value)
    assert f"dt = {sim.dt:.3e} s" in text and f"dt = {0.5 * sim.dt:.3e} s" in text
    sim.output.close()


@serial_only
def test_the_term_runs_from_the_impact_command_and_from_a_study(tmp_path, capsys):
    from fabric_fenicsx.cli import main

    scene = write_scene(tmp_path, t_end=3e-5)
    assert main(["impact", str(scene), "--out", str(tmp_path / "one"), "--quiet"]) == 0
    one = json.loads((tmp_path / "one" / "summary.json").read_text())
    assert one["energies"]["terms_dissipation"] > 0 and "viscous" in one["settings"]["membrane"]["terms"][0]["class"]
    out = tmp_path / "ens"
    assert main(["ensemble", str(scene), "-n", "2", "--jobs", "2", "--out", str(out), "--quiet"]) == 0
    for k in (0, 1):
        member = json.loads((out / f"member_{k}" / "summary.json").read_text())
        assert member["energies"]["terms_dissipation"] > 0
        assert member["dt_initial"] == pytest.approx(one["dt_initial"], rel=1e-9)
    assert main(["impact", str(write_scene(tmp_path, terms='"viscous.py:Nope"')), "--out",
                 str(tmp_path / "bad")]) == 2
    assert "has no 'Nope'" in capsys.readouterr().err


@serial_only
def test_a_material_and_a_surrogate_built_elsewhere(tmp_path):
    scene = load_scene(write_scene(tmp_path, terms=""))
    first = ImpactSimulation(scene, tmp_path / "a", verbose=False)
    assert isinstance(first.material, QuadratureMaterial)
    made = []

    def material(membrane):
        mat = YarnStress(first.surrogate, membrane.quadrature_weights_detJ, damage=False, beta=0.0)
        made.append(mat)
        return mat

    second = ImpactSimulation(scene, tmp_path / "b", verbose=False, surrogate=first.surrogate,
                              material=material)
    assert second.surrogate is first.surrogate and second.material is made[0]
    assert second.material.beta == 0.0 < first.material.beta
    assert second.dt > first.dt            # no damping: the undamped Courant limit
    for sim in (first, second):
        sim.output.close()
    with pytest.raises(TypeError, match="not a QuadratureMaterial"):
        ImpactSimulation(scene, tmp_path / "c", verbose=False, material=lambda membrane: object())


def test_the_rule_against_its_formula():
    K, rho, L, beta, eta = 2e6, 0.158, 2e-3, 1e-8, 5.0
    omega = 2 * math.sqrt(K / rho) / L
    xi = 0.5 * omega * (beta + eta / K)
    assert stable_dt(K, rho, L, beta, 0.8, eta) == pytest.approx(0.8 * 2 / omega * (math.sqrt(1 + xi * xi) - xi),
                                                                 rel=1e-14)
    assert stable_dt(K, rho, L, beta, 0.8) > stable_dt(K, rho, L, beta, 0.8, eta)
    for bad in (dict(modulus=0.0), dict(viscosity=-1.0), dict(safety=1.5)):
        args = dict(modulus=K, areal_density=rho, L_min=L, beta=beta, safety=0.8) | bad
        with pytest.raises(ValueError):
            stable_dt(**args)


@serial_only
def test_the_readme_term_named_in_a_scene_file_runs(tmp_path):
    """The README's example term, copied from the README itself, in a file named by the scene."""
    import re
    from pathlib import Path

    from fabric_fenicsx.cli import main

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    code = next(block for block in re.findall(r"```python\n(.*?)```", readme, re.S)
                if "class Pretension(MembraneTerm)" in block)
    (tmp_path / "pretension.py").write_text(code)
    scene = write_scene(tmp_path, t_end=3e-5, terms='{class = "pretension.py:Pretension", T = 200.0}')
    assert main(["impact", str(scene), "--out", str(tmp_path / "run"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["energies"]["membrane_terms"]["pretension"] > 0.0
    assert summary["energies"]["terms_dissipation"] == 0.0
