"""Impact scale: a ballistic impact on a fabric ply (thesis chapter 4).

- :mod:`.scene`: the scene schema and its validation (no DOLFINx);
- :mod:`.setup`: fabric, mesh, weak-form terms, projectile from a scene;
- :mod:`.simulation`: :class:`ImpactSimulation`, the step loop, and :func:`run_impact`;
- :mod:`.timestep`: the damped stable time step and when it is re-checked;
- :mod:`.ledger`: the energy ledger and the named reduction over ranks;
- :mod:`.removal`: deletion and erosion of cells, pieces cut loose;
- :mod:`.chatter`: statistics of the contact force;
- :mod:`.output`: XDMF, history.csv, summary.json and pictures.

Names are re-exported lazily, so importing :mod:`.scene` alone never loads DOLFINx.
"""
from fabric_fenicsx._lazy import lazy_exports

_EXPORTS = {
    "Scene": "scene", "SceneError": "scene", "load_scene": "scene", "build_scene": "scene",
    "ImpactSimulation": "simulation", "ImpactError": "simulation", "run_impact": "simulation",
    "HISTORY_COLUMNS": "simulation", "build_fabric": "setup", "EnergyLedger": "ledger",
    "stable_dt": "timestep", "CellRemoval": "removal", "chatter_statistics": "chatter",
    "ImpactOutput": "output",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
