"""Finite-element layer of fabric_fenicsx (DOLFINx 0.5.2): meshes, membrane forms, explicit dynamics.

Kept import-free on purpose: import the submodules you need, e.g.
``from fabric_fenicsx.fem.mesh import MeshSpec, load_mesh``.
"""
