"""Impact scale: a ballistic impact on a fabric ply (thesis chapter 4).

- :mod:`.scene`: the scene schema and its validation (no DOLFINx);
- :mod:`.setup`: fabric, mesh, weak-form terms, projectile from a scene;
- :mod:`.simulation`: :class:`ImpactSimulation`, the step loop, and :func:`run_impact`;
- :mod:`.term_specs`: the weak-form terms a scene names (``membrane.terms``);
- :mod:`.sizing`: a run's size estimated from its scene, too large a scene refused;
- :mod:`.lock`: one writer per output folder;
- :mod:`.summary`: summary.json; :mod:`.trouble`: messages of a run stopped on trouble;
- :mod:`.timestep`: when the stable time step is re-checked (the rule: ``fem.timestep``);
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
    "ImpactOutput": "output", "estimate": "sizing", "check_size": "sizing", "FolderLock": "lock",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
