"""Which code a run was made with, and reuse of a stored run only when it would come out the same.

The studies (``table4``, ``convergence``, ``stability``) store each impact run in its own
folder and reuse it when asked again. A stored run stands for a new one only if both its scene
settings and the code that computes an impact (:data:`MODEL_MODULES`) are unchanged: editing
a study's report writer keeps its runs, editing the physics re-runs them.

Two limits: the surrogate's tiles are cached under their own key (``tiles.cache_key``: fabric,
table settings, ``tiles.FORMAT_VERSION``), so a change to the unit cell's numbers must also
bump ``FORMAT_VERSION`` or the re-runs read the old tiles; and the version is a dump of the
syntax tree, which differs between Python minor versions (an upgrade re-runs everything).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import json
import subprocess
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent

MODEL_MODULES = ("material/*.py", "surrogate/*.py", "surrogate/kernels/*.py", "fem/*.py", "impact/*.py")
"""The package's modules (globs relative to it) whose source determines an impact run's numbers."""
NOT_MODEL = ("impact/output.py", "impact/pictures.py", "impact/warm.py")
"""Modules matched by :data:`MODEL_MODULES` that only write what a run computed."""


def code_without_prose(source: str) -> str:
    """The syntax tree of a module without its comments and its module, class and function
    docstrings, as text. (String statements elsewhere, e.g. the docstring after a constant,
    and message texts still count.)"""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree, annotate_fields=False)


@functools.lru_cache(maxsize=None)
def model_version() -> str:
    """Short SHA-256 of the :data:`MODEL_MODULES` as they were on disk when this module was
    first imported (with ``fabric_fenicsx.impact.simulation``; working-tree edits included), comments and
    docstrings left out: editing them keeps stored runs."""
    h = hashlib.sha256()
    paths = {p for pattern in MODEL_MODULES for p in PACKAGE.glob(pattern)}
    for path in sorted(p for p in paths if p.relative_to(PACKAGE).as_posix() not in NOT_MODEL):
        h.update(path.relative_to(PACKAGE).as_posix().encode())
        h.update(code_without_prose(path.read_text()).encode())
    return h.hexdigest()[:12]


def git_head() -> str:
    """Short git commit of the package's checkout ('' outside git); '+' when it has edits."""
    try:
        run = functools.partial(subprocess.run, cwd=PACKAGE, capture_output=True, text=True, timeout=10)
        head = run(["git", "rev-parse", "--short", "HEAD"]).stdout.strip()
        dirty = run(["git", "status", "--porcelain", "--", "."]).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""
    return head + ("+" if head and dirty else "")


def code_fingerprint() -> dict:
    """``{"git_head", "model_version"}`` of the code running now."""
    return {"git_head": git_head(), "model_version": model_version()}


def load_if_same(path: str | Path, settings: dict) -> dict | None:
    """The JSON record at ``path`` if it holds these ``settings`` (as JSON compares them) and
    was made by this :func:`model_version`; else None (absent, unreadable, or stale)."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        record = json.loads(path.read_text())
    except (ValueError, OSError):       # JSONDecodeError and UnicodeDecodeError are ValueErrors
        return None
    if not isinstance(record, dict) or record.get("settings") != json.loads(json.dumps(settings)):
        return None
    if record.get("model_version") != model_version():
        return None
    return record


model_version()   # pinned at import: a run records the code it was started with
