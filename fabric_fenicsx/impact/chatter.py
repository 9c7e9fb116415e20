"""Contact chatter of an impact run: how steady the contact force was (summary ``contact_chatter``)."""
from __future__ import annotations

import numpy as np

__all__ = ["chatter_statistics"]


def chatter_statistics(t: np.ndarray, force: np.ndarray, window: float = 10e-6,
                       first: float = 10e-6) -> dict:
    """Contact chatter of a contact-force history (rank 0's per-step record).

    first_touch_peak_N: the largest force within ``first`` s of the first contact, against
    plateau_mean_N, the mean force over the rest of the contact period. For consecutive
    windows of ``window`` s after the first-touch period, the ratio peak / mean force: its
    median and maximum over the windows whose mean is at least 10 % of the plateau mean
    (the fading tail after a perforation is left out)."""
    t, force = np.asarray(t, dtype=float), np.asarray(force, dtype=float)
    out = {"first_touch_peak_N": 0.0, "plateau_mean_N": 0.0, "window_s": window, "first_s": first,
           "window_peak_over_mean_median": None, "window_peak_over_mean_max": None, "n_windows": 0}
    on = np.flatnonzero(force > 0)
    if on.size == 0:
        return out
    t0, t1 = t[on[0]], t[on[-1]]
    out["first_touch_peak_N"] = float(force[(t >= t0) & (t <= t0 + first)].max())
    sel = (t > t0 + first) & (t <= t1)
    if not sel.any():
        return out
    f = force[sel]
    out["plateau_mean_N"] = float(f.mean())
    k = ((t[sel] - t0 - first) // window).astype(np.int64)
    counts = np.bincount(k)
    sums = np.bincount(k, weights=f)
    peaks = np.full(counts.size, -np.inf)
    np.maximum.at(peaks, k, f)
    keep = (counts >= 3) & (sums > 0.1 * out["plateau_mean_N"] * counts)
    ratios = peaks[keep] / (sums[keep] / counts[keep])
    if ratios.size:
        out.update(window_peak_over_mean_median=float(np.median(ratios)),
                   window_peak_over_mean_max=float(ratios.max()), n_windows=int(ratios.size))
    return out

