"""A quantity over the members of a run (the same run repeated as fabrics of other seeds, or
with its impact velocity changed by k x 1e-12): its mean with a 95 % interval, and whether one
such mean is larger than another (docs/validation.md: after damage one run is one draw, so a
finding is answered from means).

The same fabrics on two meshes (or under two rules) pair up: :func:`paired` gives the mean of
their differences, whose interval is free of the fabrics' own scatter.

Welch's test from scipy; a single member is the number itself, and
two single numbers compare as numbers (as a study with one run per case always did).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["LEVEL", "Mean", "mean_of", "larger", "all_of", "UNTOLD", "paired"]

LEVEL = 0.95
"""Confidence of the intervals and of the comparisons."""

UNTOLD = "cannot tell"
"""The answer of a comparison whose means are within each other's sampling error."""


@dataclass(frozen=True)
class Mean:
    """The mean of ``n`` members' values and the half-width of its 95 % Student-t interval
    (None for one member)."""

    mean: float
    half_width: float | None
    n: int
    sd: float | None

    def text(self, digits: int = 2) -> str:
        """``12.34`` for one member, ``12.34 +- 0.56 (n 8)`` for more."""
        if self.half_width is None:
            return f"{self.mean:.{digits}f}"
        return f"{self.mean:.{digits}f} +- {self.half_width:.{digits}f} (n {self.n})"


def mean_of(values) -> Mean | None:
    """The :class:`Mean` of the finite numbers among ``values`` (None where there is none;
    :func:`~fabric_fenicsx.studies.ensemble.statistics`)."""
    from fabric_fenicsx.studies.ensemble import statistics

    s = statistics([float(v) for v in values if v is not None and not isinstance(v, bool)])
    return None if not s["n"] else Mean(s["mean"], s["ci95"], s["n"], s["sd"])


def larger(a: Mean | None, b: Mean | None):
    """Whether ``a`` is larger than ``b``: True or False, :data:`UNTOLD` where Welch's test cannot
    tell them apart at :data:`LEVEL` (two or more members each), None where one is missing. One
    member on either side: the numbers compared as they are."""
    from scipy.stats import ttest_ind_from_stats

    if a is None or b is None:
        return None
    if a.n < 2 or b.n < 2:
        return a.mean > b.mean
    if a.sd == 0 and b.sd == 0:
        return a.mean > b.mean if a.mean != b.mean else UNTOLD
    p = ttest_ind_from_stats(a.mean, a.sd, a.n, b.mean, b.sd, b.n, equal_var=False).pvalue
    if not p < 1.0 - LEVEL:
        return UNTOLD
    return a.mean > b.mean


def all_of(answers):
    """A finding made of several comparisons: None if one is missing, False if one fails,
    :data:`UNTOLD` if none fails but one cannot be told, else True."""
    answers = list(answers)
    if any(a is None for a in answers):
        return None
    if any(a is False for a in answers):
        return False
    if any(a == UNTOLD for a in answers):
        return UNTOLD
    return True


def paired(x, y) -> dict:
    """The same members' values ``x`` and ``y`` (equal-length sequences, x[i] and y[i] of one
    fabric) compared member by member: ``n``, the mean of x - y with the half-width of its 95 %
    Student-t interval (``mean_difference``, ``difference_ci95``), the differences' sd
    (``sd_difference``) and the correlation of x and y (1 where either is constant)."""
    import math

    import numpy as np
    from scipy import stats

    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"paired: x and y must be sequences of one length, got shapes {x.shape} and {y.shape}")
    if x.size < 3:
        raise ValueError(f"paired: {x.size} members in common, at least 3 are needed")
    d = x - y
    sd = float(d.std(ddof=1))
    constant = x.std() == 0 or y.std() == 0
    return {"n": int(x.size), "mean_difference": float(d.mean()),
            "difference_ci95": float(stats.t.ppf(LEVEL / 2 + 0.5, d.size - 1) * sd / math.sqrt(d.size)),
            "sd_difference": sd, "correlation": 1.0 if constant else float(np.corrcoef(x, y)[0, 1])}
