"""Command line: ``fabric-fenicsx static | surrogate | impact | convergence | divergence | ensemble | v50 | ladder | study ...``.

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
    "v50": ("fabric_fenicsx.cli.v50",
            "the ballistic limit as a statistic: sequential runs, probit V50 with its interval, Lambert-Jonas"),
    "ladder": ("fabric_fenicsx.cli.ladder",
               "error against run time of the impact statistics: V50 and a mean residual velocity on mesh "
               "sizes, families and knob variants"),
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
    """The first SIGTERM or SIGINT: raised as :class:`Terminated` or KeyboardInterrupt; later
    ones are ignored, so that the clean-up it starts (ending runs, closing files, releasing
    locks) is not cut short (a study ends its runs with SIGTERM right after the Ctrl-C they got
    too). SIGKILL still ends a clean-up that hangs."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _default_sigterm_in_child() -> None:
    """A forked child (the surrogate's tile workers) gets SIGTERM's default action back at
    once: a Python handler runs only between bytecodes, so a worker blocked in C would never
    end when its pool terminates it, and the run would hang."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


os.register_at_fork(after_in_child=_default_sigterm_in_child)


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _value_options(parser: argparse.ArgumentParser, command: str) -> set[str]:
    """The option strings of subcommand ``command`` that take one value (``--step``, ``-n``)."""
    for action in parser._subparsers._group_actions if parser._subparsers else ():
        sub = getattr(action, "choices", {}).get(command)
        if sub is not None:
            return {o for a in sub._actions if a.option_strings and a.nargs is None
                    for o in a.option_strings}
    return set()


def join_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``argv`` with each negative number that follows an option taking a value joined onto it
    (``--perturbation -1e-12`` -> ``--perturbation=-1e-12``). argparse takes a token that starts
    with '-' and is not a plain decimal (``-1e-12``, ``-1e-3``, ``-inf``) for an option and stops
    with "expected one argument"; joined, the value reaches the command's own checks, which
    accept it or say why not. An unambiguous prefix of an option counts as argparse's does."""
    command = next((a for a in argv if a in SUBCOMMANDS), None)
    if command is None:
        return list(argv)
    options = _value_options(parser, command)
    out: list[str] = []
    for token in argv:
        prev = out[-1] if out else ""
        if "--" not in out and _is_number(token) and token.startswith("-") and prev.startswith("-") \
                and "=" not in prev and _option(prev, options):
            out[-1] = f"{prev}={token}"
        else:
            out.append(token)
    return out


def _option(token: str, options: set[str]) -> bool:
    """Whether ``token`` names one of ``options`` (exactly, or as the prefix of only one long one)."""
    if token in options:
        return True
    return token.startswith("--") and len([o for o in options if o.startswith(token)]) == 1


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    argv = join_negative_values(parser, sys.argv[1:] if argv is None else list(argv))
    args = parser.parse_args(argv)
    if getattr(args, "_missing", None):
        parser.error(args._missing)
    previous = _handle_interruptions()
    try:
        return int(importlib.import_module(args._module).run(args) or 0)
    except KeyboardInterrupt as err:
        what = "interrupted (terminated)" if isinstance(err, Terminated) else "interrupted"
        if os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0")) == "0":
            print(f"{what}: output written so far is kept", file=sys.stderr, flush=True)
        return 143 if isinstance(err, Terminated) else 130
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)                     # an in-process caller keeps its own


def _handle_interruptions() -> dict:
    """:func:`_terminate` for SIGTERM and SIGINT where they have their default handling (not
    where a caller installed its own, nor in a thread); returns ``{signal: handler}`` to put back."""
    import threading

    defaults = {signal.SIGTERM: signal.SIG_DFL, signal.SIGINT: signal.default_int_handler}
    if threading.current_thread() is not threading.main_thread():
        return {}
    previous = {sig: signal.getsignal(sig) for sig in defaults}
    previous = {sig: handler for sig, handler in previous.items() if handler is defaults[sig]}
    for sig in previous:
        signal.signal(sig, _terminate)
    return previous


if __name__ == "__main__":
    sys.exit(main())
