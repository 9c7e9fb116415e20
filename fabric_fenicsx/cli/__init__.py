"""Command line: ``fabric-fenicsx static | surrogate | impact | convergence | divergence | ensemble | study ...``.

Each subcommand's module is imported only when it runs, so the material-point scenes
never import DOLFINx.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

# subcommand -> (module, help); each module offers add_arguments(parser) and run(args) and
# imports nothing heavy (DOLFINx) at module level.
SUBCOMMANDS = {
    "static": ("fabric_fenicsx.cli.static", "static material-point scenes (thesis figures 3-1 to 3-6)"),
    "surrogate": ("fabric_fenicsx.cli.surrogate", "build or report the unit-cell surrogate"),
    "impact": ("fabric_fenicsx.cli.impact", "ballistic impact of a fabric ply (thesis chapter 4)"),
    "convergence": ("fabric_fenicsx.cli.convergence",
                    "error against run time of each discretisation knob (writes docs/convergence.md)"),
    "divergence": ("fabric_fenicsx.cli.divergence",
                   "twin runs: how fast a scene amplifies a round-off change of the impact velocity"),
    "ensemble": ("fabric_fenicsx.cli.ensemble",
                 "a scene run N times with round-off-sized changes: its answer as mean, interval and range"),
    "study": ("fabric_fenicsx.cli.study",
              "the thesis's chapter 4: Tables 4-6, friction, fillet, ballistic limit, validation report"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fabric-fenicsx",
        description="Three-scale model of woven fabrics: fibril damage, yarn unit cell, DOLFINx membrane.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (module, help_text) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module)
        try:
            importlib.import_module(module).add_arguments(p)
        except ModuleNotFoundError as err:
            if err.name != module:
                raise
            p.set_defaults(_missing=f"'{name}' is not available in this version")
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, as mpirun sends it to every rank when it is interrupted, or a batch system
    ending a job: handled as an interruption (files closed, locks released)."""


def _terminate(signum, frame):
    raise Terminated()


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_missing", None):
        parser.error(args._missing)
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(importlib.import_module(args._module).run(args) or 0)
    except KeyboardInterrupt as err:
        what = "interrupted (terminated)" if isinstance(err, Terminated) else "interrupted"
        if os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0")) == "0":
            print(f"{what}: output written so far is kept", file=sys.stderr, flush=True)
        return 143 if isinstance(err, Terminated) else 130


if __name__ == "__main__":
    sys.exit(main())
