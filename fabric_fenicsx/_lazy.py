"""Lazy re-exports for the sub-packages that import DOLFINx (PEP 562).

``fabric_fenicsx.impact.scene`` must validate a scene before DOLFINx is loaded, and ``--help``
must stay fast; yet ``from fabric_fenicsx.impact import ImpactSimulation`` should work. A
package's ``__getattr__`` imports a public name's module only when the name is first used.
"""
from __future__ import annotations

import importlib


def lazy_exports(package: str, exports: dict[str, str]):
    """(``__getattr__``, ``__dir__``) for ``package``: ``exports`` maps each public name to the
    submodule (relative to ``package``) that defines it."""

    def __getattr__(name: str):
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{exports[name]}"), name)

    def __dir__():
        return sorted(exports)

    return __getattr__, __dir__
