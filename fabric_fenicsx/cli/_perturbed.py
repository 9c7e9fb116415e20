"""Arguments shared by the commands that run a scene several times with its impact velocity
changed by a round-off-sized amount (``divergence``, ``ensemble``)."""
from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser, what: str, runs: str) -> None:
    """The scene, ``--out`` (default out/``what``-<scene name>), ``--set`` for ``runs``,
    ``--perturbation`` and ``--quiet``."""
    parser.add_argument("scene", help="scene TOML file (e.g. demos/scenes/y90.toml)")
    parser.add_argument("--out", default=None, help=f"output folder (default out/{what}-<scene name>)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help=f"override a scene key of {runs} (repeatable), e.g. --set material.damage=false")
    parser.add_argument("--perturbation", type=float, default=None,
                        help="relative change of the impact velocity between runs (default 1e-12)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def perturbation_problem(p: float) -> str | None:
    """Why ``p`` cannot be the relative change of the impact velocity, or None."""
    if not (0 < abs(p) < 1e-3):
        return f"--perturbation must be a small relative change, 0 < |p| < 1e-3, got {p!r}"
    return None
