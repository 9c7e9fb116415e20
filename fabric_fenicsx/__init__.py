"""fabric_fenicsx: the three-scale model of woven fabrics (fibril, yarn unit cell, membrane).

The tree reads as a table of contents, one sub-package per scale and concern:

- :mod:`fabric_fenicsx.material`: fabric parameters, fibril damage laws, the yarn unit cell, the
  damage coupling and the material-point contract (no DOLFINx);
- :mod:`fabric_fenicsx.surrogate`: the unit-cell table, its tiles and cache, the interpolation and
  the compiled kernels (no DOLFINx);
- :mod:`fabric_fenicsx.fem`: mesh, membrane kinematics, weak-form terms, the quadrature-point
  adapter, the explicit integrator, contact and the rigid projectile (DOLFINx);
- :mod:`fabric_fenicsx.impact`: scene schema, set-up, the step loop, time-step control, energy
  ledger, cell removal and output of an impact run;
- :mod:`fabric_fenicsx.studies`: verification and validation studies built on the above;
- :mod:`fabric_fenicsx.cli`: the ``fabric-fenicsx`` command line.
"""
