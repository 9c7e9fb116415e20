"""The package's layering, read from the source (``ast``; nothing is imported):

* the model (``fabric_fenicsx.material``, ``.surrogate``, ``.fem``, ``.impact``, ``.provenance``,
  ``._lazy`` and the package's ``__init__``) imports nothing from ``fabric_fenicsx.studies`` or
  ``fabric_fenicsx.cli``: the studies and the command line import the model, one way only;
* no module of the package is longer than :data:`MAX_LINES`;
* ``material`` and ``surrogate`` load no DOLFINx (``dolfinx``, ``ufl``, ``basix``, ``petsc4py``)
  when imported: neither they nor the package modules they import at module level import it
  outside a function.

Every ``import`` and ``from ... import`` counts, at module level or inside a function, relative
ones resolved against the module's package; ``from a import b`` counts as ``a`` and ``a.b`` (b
may be a submodule). A string given to ``importlib.import_module`` or ``__import__`` counts too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "fabric_fenicsx"
MODEL_PARTS = ("material", "surrogate", "fem", "impact")
MODEL_FILES = ("provenance.py", "_lazy.py", "__init__.py")
FORBIDDEN = ("fabric_fenicsx.studies", "fabric_fenicsx.cli")
"""The model may import neither of these nor anything below them."""
MAX_LINES = 700
DOLFINX_FREE = ("material", "surrogate")
HEAVY = ("dolfinx", "ufl", "basix", "petsc4py")
"""Top-level packages that ``material`` and ``surrogate`` must not load when imported."""


def module_name(path: Path, package: Path = PACKAGE) -> str:
    """Dotted name of a file of the package (``.../fem/mesh.py`` -> ``fabric_fenicsx.fem.mesh``)."""
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _base(path: Path, node: ast.ImportFrom, package: Path) -> str:
    """The module a ``from ... import`` names, relative levels resolved against the file's package."""
    if node.level == 0:
        return node.module or ""
    name = module_name(path, package)
    pkg = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    if node.level - 1 > len(pkg) - 1:
        raise ValueError(f"{path}:{node.lineno}: relative import beyond the top-level package")
    pkg = pkg[:len(pkg) - (node.level - 1)]
    return ".".join(pkg + ([node.module] if node.module else []))


def imports(path: Path, package: Path = PACKAGE, module_level_only: bool = False):
    """(line, imported module) of every import of one file. With ``module_level_only`` the
    imports run when the module is imported: none inside a function (class bodies and top-level
    ``if``/``try`` blocks count)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))

    def visit(node):
        for child in ast.iter_child_nodes(node):
            if module_level_only and isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                        ast.Lambda)):
                continue
            if isinstance(child, ast.Import):
                for alias in child.names:
                    yield child.lineno, alias.name
            elif isinstance(child, ast.ImportFrom):
                base = _base(path, child, package)
                yield child.lineno, base
                for alias in child.names:
                    if alias.name != "*":
                        yield child.lineno, f"{base}.{alias.name}" if base else alias.name
            elif (isinstance(child, ast.Call) and child.args
                  and isinstance(child.args[0], ast.Constant) and isinstance(child.args[0].value, str)
                  and ((isinstance(child.func, ast.Attribute) and child.func.attr == "import_module")
                       or (isinstance(child.func, ast.Name)
                           and child.func.id in ("import_module", "__import__")))):
                yield child.lineno, child.args[0].value
            yield from visit(child)

    yield from visit(tree)


def _within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def model_files(package: Path = PACKAGE) -> list[Path]:
    files = [p for part in MODEL_PARTS for p in sorted((package / part).rglob("*.py"))]
    return files + [package / name for name in MODEL_FILES]


def forbidden_imports(package: Path = PACKAGE) -> list[str]:
    """Every import of the model that reaches the studies or the command line."""
    bad = []
    for path in model_files(package):
        for line, name in imports(path, package):
            if any(_within(name, f) for f in FORBIDDEN):
                bad.append(f"{path.relative_to(package.parent)}:{line}: imports {name}")
    return bad


def long_modules(package: Path = PACKAGE, limit: int = MAX_LINES) -> list[str]:
    """Every .py file of the package with more than ``limit`` lines."""
    out = []
    for path in sorted(package.rglob("*.py")):
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > limit:
            out.append(f"{path.relative_to(package.parent)}: {n} lines")
    return out


def _file_of(name: str, package: Path) -> Path | None:
    """The file of a module of the package (None: not one, e.g. a name imported from a module)."""
    base = package.parent.joinpath(*name.split("."))
    for candidate in (base / "__init__.py", base.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None


def heavy_imports_at_import(parts=DOLFINX_FREE, package: Path = PACKAGE) -> list[str]:
    """The DOLFINx imports (:data:`HEAVY`) run when a module of ``parts`` is imported: its own
    module-level imports and those of every package module (and parent package) it loads so."""
    seen: set[Path] = set()
    todo = [p for part in parts for p in sorted((package / part).rglob("*.py"))]
    bad = []
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        name = module_name(path, package)
        parents = [".".join(name.split(".")[:k]) for k in range(1, name.count(".") + 1)]
        todo += [f for f in (_file_of(p, package) for p in parents) if f is not None]
        for line, target in imports(path, package, module_level_only=True):
            if target.split(".")[0] in HEAVY:
                bad.append(f"{path.relative_to(package.parent)}:{line}: imports {target} at module level")
            elif _within(target, package.name):
                for k in range(target.count(".") + 1, 1, -1):
                    f = _file_of(".".join(target.split(".")[:k]), package)
                    if f is not None:
                        todo.append(f)
                        break
    return bad


def test_the_model_reads_every_file_it_should():
    files = model_files()
    assert all(p.is_file() for p in files)
    for part in MODEL_PARTS:
        assert any(p.parent.relative_to(PACKAGE).parts[:1] == (part,) for p in files), part


def test_the_model_imports_neither_the_studies_nor_the_command_line():
    assert forbidden_imports() == []


def test_no_module_of_the_package_is_over_700_lines():
    assert long_modules() == []


def test_material_and_surrogate_load_no_dolfinx_when_imported():
    assert heavy_imports_at_import() == []


@pytest.mark.parametrize("source, expected", [
    ("from ..studies import static\n", "fabric_fenicsx.studies"),
    ("from .. import cli\n", "fabric_fenicsx.cli"),
    ("from fabric_fenicsx.studies.static import run_scenario\n", "fabric_fenicsx.studies.static"),
    ("import fabric_fenicsx.cli.static as s\n", "fabric_fenicsx.cli.static"),
    ("def f():\n    import importlib\n    return importlib.import_module('fabric_fenicsx.studies')\n",
     "fabric_fenicsx.studies"),
])
def test_the_import_walk_resolves_what_it_must_catch(tmp_path, source, expected):
    package = tmp_path / "fabric_fenicsx"
    (package / "fem").mkdir(parents=True)
    for init in (package / "__init__.py", package / "fem" / "__init__.py"):
        init.write_text("")
    module = package / "fem" / "bad.py"
    module.write_text(source)
    assert expected in {name for _, name in imports(module, package)}
