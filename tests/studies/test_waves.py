"""Wave speeds along warp and fill (fabric_fenicsx.studies.waves): the front and its speed on a
synthetic wave, and on a small run against sqrt(K / rho_A) of the unit cell."""
import numpy as np
import pytest

from fabric_fenicsx.studies.waves import expected_speeds, fit_speed, front_positions, wave_speeds


def test_front_and_speed_of_a_synthetic_ramp():
    """u(s, t) = -(c t - s) behind a front at c t (an axis pulled towards the impact point)."""
    s = np.linspace(0.0, 0.1, 201)
    t = np.arange(0, 30) * 1e-6
    c = 2500.0
    u = -np.maximum(c * t[:, None] - s[None, :], 0.0)
    u[0] = 1e-20                                               # before the impact: round-off only
    front = front_positions(s, u, threshold=0.01)
    assert np.isnan(front[0])
    assert front[10:] == pytest.approx(0.99 * c * t[10:], abs=0.0006)     # within a node spacing
    assert fit_speed(t, front, half_width=0.1) == pytest.approx(0.99 * c, rel=0.01)
    assert fit_speed(t[:3], front[:3], half_width=0.1) is None


def test_the_fill_wave_outruns_the_warp_wave_at_the_unit_cells_speeds(tmp_path):
    """XY0 on 120 mm of 2.5 mm squares (a node at the centre), 25 us: both fronts move at
    sqrt(K_i / rho_A) within 10 % (measured here: 1912 and 3833 m/s; on the study's 273 mm fabric of
    2 mm squares 1847 and 4003 m/s; expected 1844 and 3932 m/s), the less crimped fill about
    twice as fast as the warp."""
    from fabric_fenicsx.cli import main
    from fabric_fenicsx.material.fabric import zylon_as
    from fabric_fenicsx.studies.chapter4 import SCENE_DIR
    from fabric_fenicsx.surrogate.table import material_point

    settings = ["mesh.kind=uniform", "mesh.n=48", "mesh.side=0.12", "material.damage=false", "run.t_end=2.5e-5",
                "output.xdmf_interval=5e-7", "output.png=false", "projectile.diameter=0.02", "projectile.mass=0.005"]
    assert main(["impact", str(SCENE_DIR / "xy0.toml"), "--out", str(tmp_path / "run"), "--quiet",
                 *[a for o in settings for a in ("--set", o)]]) == 0
    measured = wave_speeds(tmp_path / "run")
    expected = expected_speeds(material_point(zylon_as()))
    assert measured["warp"] == pytest.approx(expected["warp"], rel=0.1)
    assert measured["fill"] == pytest.approx(expected["fill"], rel=0.1)
    assert 1.8 < measured["fill"] / measured["warp"] < 2.6
