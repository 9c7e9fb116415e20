"""Weak-form terms named in a scene file: ``membrane.terms``.

A scene adds a user's term (a :class:`~fabric_fenicsx.fem.terms.MembraneTerm` subclass) to the
membrane by naming its class, so that ``fabric-fenicsx impact``, the ensembles and the studies
run it like the built-in ones::

    [membrane]
    terms = ["mypackage.terms:Pretension"]                       # no keyword arguments
    terms = [{class = "mypackage.terms:Pretension", T = 200.0}]  # keyword arguments
    terms = [{class = "terms/pretension.py:Pretension", T = 200.0}]

The part before the colon is an importable module (on ``sys.path``/``PYTHONPATH``) or a Python
file, relative to the scene file's folder (to the working folder without one); a file is made
absolute when the scene is loaded, so the run's recorded settings repeat it from anywhere. The
class is imported and its keyword arguments are bound to its signature when the scene is
loaded, so a bad name or argument stops before any work. Nothing here imports DOLFINx.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import sys
from pathlib import Path
from typing import Any

__all__ = ["check_term_specs", "resolve_term_specs", "build_scene_terms"]

_FORM = ('a list of "module:Class" or "file.py:Class" strings or tables '
         '{class = "module:Class", key = value, ...}')


def check_term_specs(name: str, value: Any) -> list:
    """Scene checker of ``membrane.terms``: the shape only (the classes are resolved by
    :func:`resolve_term_specs` once the scene's folder is known)."""
    from fabric_fenicsx.impact.scene import SceneError

    if isinstance(value, (str, dict)):
        value = [value]
    if not isinstance(value, (list, tuple)):
        raise SceneError(f"{name} = {value!r}: must be {_FORM}")
    specs = []
    for item in value:
        target = item.get("class") if isinstance(item, dict) else item
        if not isinstance(target, str) or target.count(":") != 1 or not all(target.split(":")):
            raise SceneError(f"{name}: {item!r} is not a term: give {_FORM}")
        specs.append(dict(item) if isinstance(item, dict) else item)
    return specs


check_term_specs.kind = "list of term classes"


def _split(spec) -> tuple[str, dict]:
    if isinstance(spec, dict):
        kwargs = {k: v for k, v in spec.items() if k != "class"}
        return spec["class"], kwargs
    return spec, {}


def _load_class(target: str, base: Path):
    """(class, target with a file made absolute) for ``module:Class`` or ``file.py:Class``."""
    from fabric_fenicsx.impact.scene import SceneError

    where, cls_name = target.split(":")
    if where.endswith(".py"):
        path = Path(where)
        path = path if path.is_absolute() else (base / path).resolve()
        if not path.is_file():
            raise SceneError(f"membrane.terms: {target!r}: no such file {path}")
        mod_name = "fabric_fenicsx_user_terms_" + hashlib.sha256(str(path).encode()).hexdigest()[:12]
        module = sys.modules.get(mod_name)
        if module is None:
            spec = importlib.util.spec_from_file_location(mod_name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[mod_name] = module
            try:
                spec.loader.exec_module(module)
            except Exception as err:
                del sys.modules[mod_name]
                raise SceneError(f"membrane.terms: {target!r}: {path} failed to import: "
                                 f"{type(err).__name__}: {err}") from None
        target = f"{path}:{cls_name}"
    else:
        try:
            module = importlib.import_module(where)
        except Exception as err:
            raise SceneError(f"membrane.terms: {target!r}: module {where!r} cannot be imported "
                             f"({type(err).__name__}: {err}); put it on PYTHONPATH or name a file "
                             "path ending in .py") from None
    cls = getattr(module, cls_name, None)
    if cls is None:
        raise SceneError(f"membrane.terms: {target!r}: {where} has no {cls_name!r}")
    return cls, target


def resolve_term_specs(specs: list, base: Path) -> list:
    """Import every term class of ``specs``, check that it is a MembraneTerm and that its
    keyword arguments fit its signature; return the specs with file paths made absolute
    (relative to ``base``). Raises :class:`~fabric_fenicsx.impact.scene.SceneError`."""
    from fabric_fenicsx.fem.terms import MembraneTerm
    from fabric_fenicsx.impact.scene import SceneError

    resolved = []
    for spec in specs:
        target, kwargs = _split(spec)
        cls, target = _load_class(target, base)
        if not (isinstance(cls, type) and issubclass(cls, MembraneTerm)):
            raise SceneError(f"membrane.terms: {target!r} is not a subclass of "
                             "fabric_fenicsx.fem.terms.MembraneTerm")
        try:
            inspect.signature(cls).bind(**kwargs)
        except TypeError as err:
            raise SceneError(f"membrane.terms: {target!r} with arguments {kwargs}: {err}; its "
                             f"signature is {cls.__name__}{inspect.signature(cls)}") from None
        resolved.append({"class": target, **kwargs} if kwargs or isinstance(spec, dict) else target)
    return resolved


def build_scene_terms(specs: list) -> list:
    """The term instances of resolved ``specs`` (:func:`resolve_term_specs`), in order."""
    terms = []
    for spec in specs:
        target, kwargs = _split(spec)
        cls, _ = _load_class(target, Path.cwd())
        terms.append(cls(**kwargs))
    return terms
