"""Compiled (numba) kernels of the constitutive update, each beside the Python code it is tested
against:

- :mod:`.interp`: the surrogate's look-up with derivatives (reference: the unit cell at the
  table's nodes, tests/surrogate/test_surrogate.py);
- :mod:`.damage`: the damage iteration, which compiles the very functions of
  :mod:`fabric_fenicsx.material.damage_solver` that the unit cell runs in Python;
- :mod:`.yarn_stress`: the slack rule, viscous yarn stress and its work for the quadrature-point
  adapter :class:`fabric_fenicsx.fem.yarn_stress.YarnStress`;
(:mod:`fabric_fenicsx.impact.warm`, a short impact run, fills numba's cache with every kernel a
run compiles; ``make setup`` runs it beside pip.)
"""
