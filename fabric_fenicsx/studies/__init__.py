"""Studies built on the model: verification (Smith's transverse impact, convergence, stability
on stiff and extreme cases, the surrogate's accuracy), validation (the thesis's Table 4) and the
static material-point scenes of chapter 3. Stored runs are reused by their provenance
(:mod:`fabric_fenicsx.provenance`, part of the model).

- :mod:`.static`: the material-point scenes of chapter 3 (no DOLFINx; split into
  :mod:`.static_scenarios`, :mod:`.static_points` and :mod:`.static_report`);
- :mod:`.smith`: Smith's theory of a transverse impact on a yarn, and the membrane against it;
- :mod:`.convergence`, :mod:`.convergence_report`: error against run time of every knob;
- :mod:`.stability`: the impact driver on stiff and extreme cases (with
  :mod:`.stability_cases` and :mod:`.stability_report`);
- :mod:`.table4`: Y90 at the five velocities of Table 4;
- :mod:`.surrogate_report`: the surrogate against the unit cell;

Names are re-exported lazily (the impact studies load DOLFINx only when they run).
"""
from fabric_fenicsx._lazy import lazy_exports

_EXPORTS = {
    "run_scenario": "static", "UnitCellPoint": "static", "SCENARIOS": "static",
    "smith_theory": "smith", "simulate_transverse_impact": "smith",
    "run_report": "surrogate_report",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
