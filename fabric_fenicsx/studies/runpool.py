"""Independent impact runs of a study, ``jobs`` at a time, each a ``fabric-fenicsx impact``
process of its own; a run whose summary.json is stored with the same settings and model version
(:mod:`fabric_fenicsx.provenance`) is reused, not run again, so an interrupted study
resumes where it stopped; so is a run that failed (failed.json: its error, settings and model
version), which would fail the same way again (a run killed or interrupted is run again).

A run is a :class:`Run` (a folder name, a scene file, ``--set`` overrides); :func:`run_all`
returns each run's summary, or a row with ``error`` (the exit code and the last line of its
log) for a run that failed. Each process runs serially (one rank, one thread).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["Run", "run_all"]


@dataclass(frozen=True)
class Run:
    """One impact run of a study: into ``out_dir``/``key``, the scene file with ``overrides``."""

    key: str
    scene: str
    overrides: tuple = field(default_factory=tuple)


def _command(run: Run, folder: Path) -> list[str]:
    return [sys.executable, "-m", "fabric_fenicsx.cli", "impact", str(run.scene), "--out", str(folder),
            "--quiet", *[a for o in run.overrides for a in ("--set", o)]]


def _settings(run: Run) -> dict:
    from fabric_fenicsx.impact.scene import load_scene

    return load_scene(run.scene, list(run.overrides)).to_dict()


def _stored(run: Run, folder: Path) -> dict | None:
    """The run's stored summary, or its stored failure (failed.json: the same settings and model
    version fail the same way), or None."""
    from fabric_fenicsx.provenance import load_if_same

    settings = _settings(run)
    return load_if_same(folder / "summary.json", settings) or load_if_same(folder / "failed.json", settings)


def run_all(runs: list[Run], out_dir: str | Path, jobs: int = 1, on_done=None, reuse: bool = True,
            slots=None) -> dict:
    """Run (or, with ``reuse``, take the stored result of) every run, ``jobs`` processes at a
    time; ``on_done(run, summary, reused)`` is called as each one ends. ``slots``: a
    ``threading.Semaphore`` shared by calls in other threads, of which every process holds one
    while it runs (so that concurrent calls together keep to the cores). Returns
    ``{key: summary}`` (a failed run: ``{"error": ...}``)."""
    out_dir = Path(out_dir)
    keys = [r.key for r in runs]
    if len(set(keys)) != len(keys):
        raise ValueError(f"the runs' keys must differ (they name their folders), got {keys}")
    results: dict[str, dict] = {}
    pending = []
    for run in runs:
        stored = _stored(run, out_dir / run.key) if reuse else None
        if stored is not None:
            results[run.key] = stored
            if on_done is not None:
                on_done(run, stored, True)
        else:
            pending.append(run)
    running: dict = {}
    env = dict(os.environ, OMP_NUM_THREADS="1")
    while pending or running:
        while pending and len(running) < max(1, jobs) and (slots is None or slots.acquire(blocking=False)):
            run = pending.pop(0)
            folder = out_dir / run.key
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "summary.json").unlink(missing_ok=True)   # never read an older run's
            (folder / "failed.json").unlink(missing_ok=True)
            log = open(folder / "run.log", "w")
            try:
                proc = subprocess.Popen(_command(run, folder), stdout=log, stderr=subprocess.STDOUT, env=env)
            except BaseException:
                log.close()
                if slots is not None:
                    slots.release()
                raise
            running[run.key] = (proc, run, folder, log)
        time.sleep(0.2)
        for key in [k for k, (p, *_) in running.items() if p.poll() is not None]:
            proc, run, folder, log = running.pop(key)
            log.close()
            if slots is not None:
                slots.release()
            try:
                summary = json.loads((folder / "summary.json").read_text())
                if proc.returncode != 0:
                    raise ValueError("the run failed after writing a summary")
            except (OSError, ValueError):
                lines = (folder / "run.log").read_text(errors="replace").strip().splitlines()
                summary = {"error": f"exit code {proc.returncode}: {lines[-1] if lines else 'no output'}"}
                if proc.returncode > 0 and proc.returncode != 130:   # not killed, not interrupted
                    _record_failure(run, folder, summary)
            results[key] = summary
            if on_done is not None:
                on_done(run, summary, False)
    return {k: results[k] for k in keys}


def _record_failure(run: Run, folder: Path, summary: dict) -> None:
    """failed.json beside the run's log: its error, settings and model version, so that the
    study reports it again instead of repeating a run that fails the same way."""
    from fabric_fenicsx.provenance import model_version

    try:
        settings = _settings(run)
    except Exception:        # the scene itself is bad: nothing to reuse
        return
    (folder / "failed.json").write_text(json.dumps({**summary, "settings": settings,
                                                    "model_version": model_version()}, indent=1))
