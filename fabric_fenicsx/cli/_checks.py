"""Checks the statistics commands (v50, ladder, study) make before any work: each returns the
one line that says what is wrong (None when nothing is), and none leaves a folder behind; and
how many runs may go at once in the memory there is."""
from __future__ import annotations

import math
import os
from pathlib import Path


def scene_problem(scene) -> str | None:
    """An empty SCENE argument (a path that would name the working folder)."""
    if scene is not None and not str(scene).strip():
        return "SCENE is empty: give a scene file (e.g. demos/scenes/y90.toml)"
    return None


def positive_problem(option: str, value, unit: str) -> str | None:
    """``option`` given (not None) but not a finite number > 0."""
    if value is None or (math.isfinite(value) and value > 0):
        return None
    return f"{option} must be a finite number > 0 {unit}, got {value}"


def parse_bracket(text: str) -> tuple[float, float]:
    """``LO,HI`` of ``--bracket`` as the design accepts it (finite, from its floor up), else a
    ValueError with the line to print."""
    from fabric_fenicsx.studies.neyer import NeyerDesign

    floor = NeyerDesign(2.0, 3.0).floor
    problem = (f"--bracket must be LO,HI with {floor:g} <= LO < HI, both finite (m/s; the design never goes "
               f"below {floor:g} m/s), got {text!r}")
    try:
        lo, hi = (float(x) for x in text.split(","))
        NeyerDesign(lo, hi)
    except ValueError:
        raise ValueError(problem) from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(problem)
    return lo, hi


def first_missing(path: Path) -> Path | None:
    """The outermost folder of ``path`` that does not exist yet (None if ``path`` exists)."""
    missing = None
    for p in (path, *path.parents):
        if p.exists() or p.is_symlink():
            break
        missing = p
    return missing


def remove_new(path: Path, first_missing: Path | None) -> None:
    """Remove the empty folders from ``path`` up to ``first_missing`` (those a check made)."""
    if first_missing is None:
        return
    for p in (path, *path.parents):
        try:
            p.rmdir()
        except OSError:
            return
        if p == first_missing:
            return


def out_problem(out) -> str | None:
    """What is wrong with the output folder ``out`` (empty, a file, not creatable, not
    writable); the folders the check had to create are removed again."""
    from fabric_fenicsx.impact.scene import InputError, check_output_dir

    if not str(out).strip():
        return "--out is empty: give a folder (or leave --out out for the default)"
    path = Path(out)
    first = first_missing(path)
    try:
        check_output_dir(str(path))
    except InputError as err:
        return str(err)
    finally:
        remove_new(path, first)
    return None


def memory_jobs(jobs: int, scenes, say, scheduler: str | None = None) -> int:
    """``jobs`` capped to the runs that fit in the free memory at once, each of the size
    :mod:`fabric_fenicsx.impact.sizing` estimates for the largest of ``scenes``, at least 1;
    ``say`` is told when it caps. Runs on another machine (``scheduler`` tcp://...) are not
    capped here; those of ``local:N`` are."""
    from fabric_fenicsx.impact.sizing import estimate, free_memory

    free = free_memory()
    if free is None or (scheduler is not None and not scheduler.startswith("local:")):
        return jobs
    each = max(estimate(scene).memory for scene in scenes)
    fit = max(1, int(free // each))
    if jobs > fit:
        say(f"{fit} runs at a time instead of {jobs}: each needs about {each / 1e6:,.0f} MB (the run's size "
            f"estimate) and {free / 1e6:,.0f} MB are free")
        return fit
    return jobs


def cpu_count() -> int:
    """The cores this process may use."""
    return len(os.sched_getaffinity(0))


def doc_problem(doc) -> str | None:
    """What is wrong with the report file ``doc`` (``study chapter4 --doc``): empty, a folder, or
    in a folder that cannot be made or written (its pictures go to a folder beside it)."""
    if not str(doc).strip():
        return "--doc is empty: give the report's file (default docs/validation.md)"
    path = Path(doc)
    if path.is_dir():
        return f"--doc {str(path)!r} is a folder; give the report's file (e.g. {path / 'validation.md'})"
    if path.exists() and not os.access(path, os.W_OK):
        return f"--doc {str(path)!r} cannot be written; give a writable file"
    pictures = path.parent / path.stem
    if pictures.exists() and not pictures.is_dir():
        return f"--doc {str(path)!r}: its pictures' folder {str(pictures)!r} is a file; give another --doc"
    problem = out_problem(path.parent if str(path.parent) else ".")
    return None if problem is None else problem.replace("output folder (--out)", "--doc's folder")
