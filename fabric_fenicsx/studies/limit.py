"""The ballistic limit by bisection, with the run-to-run scatter near it kept as a band
(docs/validation.md, ``fabric-fenicsx study v50``).

At every velocity tried, ``evaluate(v)`` returns the outcomes of a few runs (True: perforated),
for example members whose impact velocity differs in the 12th digit. Where the outcomes scatter,
one velocity can hold in one member and perforate in another, so there are two edges: the lowest
velocity at which some run perforates and the lowest at which every run does. Each is found by
its own bisection (the second reuses the velocities the first tried), and the band runs from the
highest velocity tried at which every run held to the lowest at which every run perforated. For
a sharp limit the band is the final bracket; its midpoint is reported as the limit. Pure Python:
the caller decides what a run is.
"""
from __future__ import annotations

__all__ = ["bisect_limit"]


def bisect_limit(evaluate, lo: float, hi: float, tol: float = 0.5, expand: int = 3,
                 floor: float = 1.0, on_step=None) -> dict:
    """Ballistic limit of ``evaluate`` (v -> list of bool, True = perforated) between ``lo``
    and ``hi`` (m/s), both edges bisected until narrower than ``tol``. If some run perforates at
    ``lo``, it is halved (not below ``floor``); if not every run perforates at ``hi``, it is
    doubled; at most ``expand`` times each. ``on_step(v, outcomes)`` follows every new velocity.

    Returns ``{"limit": the band's midpoint or None, "band": (every run held, every run
    perforated), "lower": bracket of the first perforation, "upper": bracket of the last hold,
    "tries": [(v, outcomes), ...], "found": bool}``; without a limit, the band has None on the
    side that was never reached."""
    if not 0 < lo < hi or tol <= 0:
        raise ValueError(f"need 0 < lo < hi and tol > 0, got lo={lo!r}, hi={hi!r}, tol={tol!r}")
    seen: dict[float, list[bool]] = {}

    def outcomes(v: float) -> list[bool]:
        if v not in seen:
            result = [bool(o) for o in evaluate(v)]
            if not result:
                raise ValueError(f"evaluate({v!r}) returned no outcome")
            seen[v] = result
            if on_step is not None:
                on_step(v, result)
        return seen[v]

    for _ in range(expand + 1):
        if not any(outcomes(lo)):
            break
        if lo <= floor:
            return _result(seen, None, None)
        lo = max(floor, lo / 2)
    else:
        return _result(seen, None, None)
    for _ in range(expand + 1):
        if all(outcomes(hi)):
            break
        hi *= 2
    else:
        return _result(seen, None, None)
    lower = _edge(outcomes, seen, any, tol)
    upper = _edge(outcomes, seen, all, tol)
    return _result(seen, lower, upper)


def _edge(outcomes, seen: dict, test, tol: float) -> tuple[float, float]:
    """Bisect the velocity where ``test(outcomes)`` turns true, from the tightest bracket the
    velocities already tried give (they include a false one below a true one)."""
    lo = max(v for v, o in seen.items() if not test(o) and any(test(seen[w]) for w in seen if w > v))
    hi = min(v for v, o in seen.items() if test(o) and v > lo)
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if test(outcomes(mid)):
            hi = mid
        else:
            lo = mid
    return lo, hi


def _result(seen: dict, lower, upper) -> dict:
    tries = sorted(seen.items())
    if lower is None:
        held = [v for v, o in tries if not any(o)]
        through = [v for v, o in tries if all(o)]
        band = (max(held) if held else None, min(through) if through else None)
        return {"limit": None, "band": band, "lower": None, "upper": None, "tries": tries, "found": False}
    band = (lower[0], upper[1])
    return {"limit": 0.5 * (band[0] + band[1]), "band": band, "lower": lower, "upper": upper,
            "tries": tries, "found": True}
