"""The velocities of a ballistic-limit estimate, chosen one batch at a time: Neyer's D-optimal
sensitivity test (B. T. Neyer, "A D-optimality-based sensitivity test", Technometrics 36 (1994)
61-70), for ``fabric-fenicsx v50``.

Why this design: every shot should add as much as it can to what the probit fit
(:mod:`fabric_fenicsx.studies.probit`) needs, V50 and the spread sigma (V50's interval widens
with sigma's uncertainty, and V10, V90 need sigma). Neyer's test does that by placing each shot
where it maximises the determinant of the Fisher information of (V50, sigma) at the current
estimate, which puts shots near 13 % and 87 % probability, not all at V50; an up-and-down
(Bruceton) or Langlie test spends its shots near V50 and learns sigma slowly, and a fixed grid
spends most of them where the outcome is all but certain (tests/studies/test_probit.py measures
the runs each needs to a given width). The three phases:

1. *bracket*: the first batch spreads over (lo, hi); until both outcomes are seen, shots step
   down from the slowest perforation or up from the fastest hold by (hi - lo) / 2 (a batch of k
   spread over that step), the step doubling with each shot beyond the bracket (not below ``floor``, not above ``ceiling``, default 4 hi);
2. *overlap*: while every hold is slower than every perforation (no likelihood maximum): where
   the gap between them is wider than the guessed spread sigma_g, shots go into it, equally
   spaced (a bisection); where it is narrower, shots go where the D-optimal rule of phase 3
   puts them for V50 at the gap's middle and sigma = sigma_g (outside the gap, where a hold
   above a perforation or the reverse makes the overlap), and sigma_g shrinks by 0.8 per such
   shot (Neyer's rule). sigma_g starts at (hi - lo) / 8. A gap no wider than ``resolution``
   is a sharp limit and the design ends;
3. *D-optimal*: shots at the velocity that maximises det(I + I(v)), the information I of the
   shots so far (those still running included: the information does not depend on the outcome)
   at the probit estimate, sigma kept within [resolution, hi - lo] for the design only.

A batch of k shots (k runs at once) is chosen greedily, each shot counting the batch's earlier
ones. Velocities are rounded to ``resolution``; the design is a pure function of the shots
so far, so a resumed estimate chooses the same velocities again.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NeyerDesign", "Shot"]


@dataclass(frozen=True)
class Shot:
    """A shot of the design: its velocity (m/s) and outcome (True perforated, False held, None
    running or not counted)."""

    velocity: float
    perforated: bool | None = None


@dataclass(frozen=True)
class NeyerDesign:
    """Neyer's sequential design started from the bracket (lo, hi) (m/s)."""

    lo: float
    hi: float
    resolution: float = 0.01
    floor: float = 1.0
    ceiling: float | None = None

    def __post_init__(self):
        if not (0 < self.floor <= self.lo < self.hi) or self.resolution <= 0:
            raise ValueError(f"need 0 < floor <= lo < hi and resolution > 0, got floor={self.floor!r}, "
                             f"lo={self.lo!r}, hi={self.hi!r}, resolution={self.resolution!r}")

    @property
    def top(self) -> float:
        return self.ceiling if self.ceiling is not None else 4.0 * self.hi

    def phase(self, shots) -> str:
        """``bracket``, ``overlap``, ``d-optimal``, or ``sharp`` (done: no overlap in a gap of at most
        the resolution between the fastest hold and the slowest perforation; both outcomes at one
        velocity are ``overlap``) / ``unbracketed`` (done: perforates at the floor or holds at the
        ceiling)."""
        from fabric_fenicsx.studies.probit import separation

        done = [s for s in shots if s.perforated is not None]
        if not done:
            return "bracket"
        held = [s.velocity for s in done if not s.perforated]
        through = [s.velocity for s in done if s.perforated]
        if not held or not through:
            if through and min(through) <= self.floor or held and max(held) >= self.top:
                return "unbracketed"
            return "bracket"
        gap = separation([s.velocity for s in done], [s.perforated for s in done])
        if gap is None:
            return "d-optimal"
        # a hold and a perforation at one velocity is no sharp limit: the design goes on around it
        return "sharp" if 0.0 < gap[1] - gap[0] <= self.resolution else "overlap"

    def next(self, shots, k: int = 1) -> list[float]:
        """The next ``k`` velocities after ``shots`` (a list of :class:`Shot`, those still running
        with outcome None); [] when the design has ended (see :meth:`phase`)."""
        shots = list(shots)
        phase = self.phase(shots)
        if phase in ("sharp", "unbracketed"):
            return []
        if phase == "bracket":
            out = self._bracket(shots, k)
        elif phase == "overlap":
            out = self._gap(shots, k)
        else:
            out = self._d_optimal(shots, k, *self._estimate(shots))
        return [self._round(v) for v in out]

    def sigma_guess(self, shots) -> float:
        """sigma_g after ``shots``: (hi - lo) / 8, times 0.8 for each shot placed outside a gap
        narrower than sigma_g (replayed from the shots' order, so the same shots give the same
        value)."""
        sigma = (self.hi - self.lo) / 8.0
        for i in range(len(shots)):
            before = [s for s in shots[:i] if s.perforated is not None]
            gap = self._separated_gap(before)
            if gap is not None and gap[1] - gap[0] <= sigma:
                sigma *= 0.8
        return sigma

    @staticmethod
    def _separated_gap(done) -> tuple | None:
        from fabric_fenicsx.studies.probit import separation

        held = [s for s in done if not s.perforated]
        if not held or len(held) == len(done):
            return None
        return separation([s.velocity for s in done], [s.perforated for s in done])

    def _round(self, v: float) -> float:
        return round(float(np.clip(round(v / self.resolution) * self.resolution, self.floor, self.top)), 9)

    def _bracket(self, shots, k: int) -> list[float]:
        tried = [s.velocity for s in shots]
        if not tried:
            return list(self.lo + (self.hi - self.lo) * np.arange(1, k + 1) / (k + 1))
        done = [s for s in shots if s.perforated is not None]
        if not done:                                   # everything still running: spread out
            return list(np.linspace(self.lo, self.hi, k + 2)[1:-1] + 0.5 * self.resolution)
        step = 0.5 * (self.hi - self.lo)
        if all(s.perforated for s in done):
            start = min(s.velocity for s in done)
            n_down = sum(1 for v in tried if v < self.lo)
            out = [max(self.floor, start - step * 2.0 ** n_down * (i + 1) / k) for i in range(k)]
        else:
            start = max(s.velocity for s in done)
            n_up = sum(1 for v in tried if v > self.hi)
            out = [min(self.top, start + step * 2.0 ** n_up * (i + 1) / k) for i in range(k)]
        return sorted(set(out), key=out.index)

    def _gap(self, shots, k: int) -> list[float]:
        done = [s for s in shots if s.perforated is not None]
        held = max(s.velocity for s in done if not s.perforated)
        through = min(s.velocity for s in done if s.perforated)
        sigma_g = self.sigma_guess(shots)
        if through - held <= sigma_g:
            return self._d_optimal(shots, k, 0.5 * (held + through), max(sigma_g, self.resolution))
        running = sorted(s.velocity for s in shots if s.perforated is None and held < s.velocity < through)
        edges = [held, *running, through]
        out = []
        for _ in range(k):                             # split the widest remaining piece
            i = int(np.argmax(np.diff(edges)))
            mid = 0.5 * (edges[i] + edges[i + 1])
            out.append(mid)
            edges.insert(i + 1, mid)
        return out

    def _estimate(self, shots) -> tuple[float, float]:
        """(V50, sigma) of the probit fit of the counted shots, sigma within [resolution, hi - lo];
        where the fitted slope is not positive, the middle of the outcomes' overlap and sigma_g."""
        from fabric_fenicsx.studies.probit import fit_probit

        done = [s for s in shots if s.perforated is not None]
        fit = fit_probit([s.velocity for s in done], [s.perforated for s in done], intervals="none")
        if fit is None:
            held = max(s.velocity for s in done if not s.perforated)
            through = min(s.velocity for s in done if s.perforated)
            return 0.5 * (held + through), self.sigma_guess(shots)
        return fit.v50, float(np.clip(fit.sigma, self.resolution, self.hi - self.lo))

    def _d_optimal(self, shots, k: int, v50: float, sigma: float) -> list[float]:
        from fabric_fenicsx.studies.probit import probit_information

        info = probit_information([s.velocity for s in shots], v50, sigma)
        candidates = np.clip(v50 + sigma * np.linspace(-3.0, 3.0, 601), self.floor, self.top)
        each = probit_information(candidates, v50, sigma, each=True)
        out = []
        for _ in range(k):
            best = float(candidates[int(np.argmax(np.linalg.det(info + each)))])
            out.append(best)
            info = info + probit_information([best], v50, sigma)
        return out
