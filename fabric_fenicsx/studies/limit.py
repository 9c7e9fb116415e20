"""The ballistic limit by bisection between a velocity the fabric holds and one it lets through,
with the run-to-run scatter near the limit kept as a band (issue 15, ``fabric-fenicsx study v50``).

At every velocity tried, ``evaluate(v)`` returns the outcomes of a few runs (True: perforated),
for example members whose impact velocity differs in the 12th digit. The bisection moves the
upper end to a velocity where at least half of them perforated and the lower end to one where
fewer did. Where the outcomes scatter, a velocity can hold in one member and perforate in
another; the band is therefore the final bracket widened to the lowest velocity at which any run
perforated and the highest at which any run held. Pure Python: the
caller decides what a run is.
"""
from __future__ import annotations

__all__ = ["bisect_limit"]


def bisect_limit(evaluate, lo: float, hi: float, tol: float = 0.5, expand: int = 3,
                 floor: float = 1.0, on_step=None) -> dict:
    """Ballistic limit of ``evaluate`` (v -> list of bool, True = perforated) between ``lo``
    and ``hi`` (m/s), bisected until the bracket is narrower than ``tol``. If ``lo`` already
    perforates, it is halved (not below ``floor``), and if ``hi`` holds, it is doubled, at most
    ``expand`` times each. ``on_step(v, outcomes)`` is called after every velocity.

    Returns ``{"limit": midpoint of the final bracket or None, "bracket": (v_held, v_perforated),
    "band": (low, high), "tries": [(v, outcomes), ...], "found": bool}``."""
    if not 0 < lo < hi or tol <= 0:
        raise ValueError(f"need 0 < lo < hi and tol > 0, got lo={lo!r}, hi={hi!r}, tol={tol!r}")
    tries: list[tuple[float, list[bool]]] = []

    def perforates(v: float) -> bool:
        outcomes = [bool(o) for o in evaluate(v)]
        if not outcomes:
            raise ValueError(f"evaluate({v!r}) returned no outcome")
        tries.append((v, outcomes))
        if on_step is not None:
            on_step(v, outcomes)
        return 2 * sum(outcomes) >= len(outcomes)

    for _ in range(expand + 1):
        if not perforates(lo):
            break
        if lo <= floor:
            return _result(tries, None, (None, lo))
        hi, lo = lo, max(floor, lo / 2)
    else:
        return _result(tries, None, (None, hi))      # every lower end tried perforated
    for _ in range(expand + 1):
        if perforates(hi):
            break
        lo, hi = hi, 2 * hi
    else:
        return _result(tries, None, (lo, None))      # every upper end tried held
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if perforates(mid):
            hi = mid
        else:
            lo = mid
    return _result(tries, 0.5 * (lo + hi), (lo, hi))


def _result(tries, limit, bracket) -> dict:
    """The band: the final bracket, widened to every velocity at which the runs disagreed with
    it (a perforation below its upper end, a hold above its lower end)."""
    lo, hi = bracket
    perforated = [v for v, o in tries if any(o)]
    held = [v for v, o in tries if not all(o)]
    band_lo = min([v for v in (lo, *perforated) if v is not None], default=None)
    band_hi = max([v for v in (hi, *held) if v is not None], default=None)
    if lo is None or hi is None:
        band_lo, band_hi = lo, hi
    return {"limit": limit, "bracket": bracket, "band": (band_lo, band_hi), "tries": tries,
            "found": limit is not None}
