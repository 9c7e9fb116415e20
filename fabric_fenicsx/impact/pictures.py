"""Pictures of the deformed fabric: ``snapshots.png`` (at damage onset, at the largest
central deflection and at the end, coloured by the warp's integrity SDV2 = alpha1, with a colour
bar and a scale bar) and, with ``output.animation``, ``impact.gif`` (the fabric every
``output.animation_interval`` of simulated time).

:class:`FabricPictures` keeps copies of the states it is shown (each rank its own cells, cheap:
a displacement and a damage array per state) and renders at the end on rank 0: pyvista draws the
3D view off-screen and matplotlib adds the colour bar and scale bar (VTK's own scalar bar cannot
be used in a process that imported DOLFINx first: see ``ImpactOutput._damage_map``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from fabric_fenicsx.impact.output import cell_corners

__all__ = ["FabricPictures", "SNAPSHOTS", "ANIMATION"]

SNAPSHOTS = "snapshots.png"
ANIMATION = "impact.gif"


class FabricPictures:
    """States of the deformed fabric kept during a run, and their pictures at the end
    (collective: :meth:`write` on every rank)."""

    def __init__(self, membrane, comm, animation_interval: float = 0.0):
        m = membrane
        self.m, self.comm = m, comm
        self.nodes = cell_corners(m.V, m.n_cells)
        self.X = m.V.tabulate_dof_coordinates()[:, :3].copy()
        self.X[:, 2] = 0.0
        self.snapshots: dict[str, tuple] = {}
        self.frames: list[tuple] = []
        self.animation_interval = float(animation_interval)
        self.next_frame = 0.0 if self.animation_interval > 0 else np.inf

    def _state(self, t: float, deflection: float, alpha1: np.ndarray, live: np.ndarray) -> tuple:
        # plain copies only: "largest deflection" is kept at every step while the fabric deflects
        return (t, deflection, self.m.u.x.array.copy(), np.array(alpha1, copy=True),
                np.array(live[:self.m.n_cells], dtype=bool, copy=True))

    def keep(self, name: str, t: float, deflection: float, alpha1: np.ndarray, live: np.ndarray) -> None:
        """Keep the current state (u of the membrane, alpha1 at the points, the live cells) as
        snapshot ``name`` (a later call with the same name replaces it)."""
        self.snapshots[name] = self._state(t, deflection, alpha1, live)

    def frame_due(self, t: float) -> bool:
        return t >= self.next_frame

    def add_frame(self, t: float, deflection: float, alpha1: np.ndarray, live: np.ndarray) -> None:
        """Keep an animation frame and schedule the next."""
        self.frames.append(self._state(t, deflection, alpha1, live))
        self.next_frame = t + self.animation_interval

    def _gathered(self, states: list[tuple]):
        """Per state on rank 0: (t, deflection, deformed quads (n, 4, 3), alpha1, live)."""
        n = self.m.n_cells
        local = [(self.X[self.nodes] + u.reshape(-1, 3)[self.nodes], a.reshape(n, -1).mean(axis=1), live)
                 for (_, _, u, a, live) in states]
        parts = self.comm.gather(local, root=0)
        if self.comm.rank != 0:
            return None
        out = []
        for i, (t, d, *_rest) in enumerate(states):
            quads = np.concatenate([p[i][0] for p in parts])
            alpha = np.concatenate([p[i][1] for p in parts])
            live = np.concatenate([p[i][2] for p in parts])
            out.append((t, d, quads, alpha, live))
        return out

    def write(self, out_dir: Path, snapshots: bool = True) -> None:
        """Render ``snapshots.png`` (if asked and any state was kept) and ``impact.gif`` (if
        frames were kept) into ``out_dir`` (collective)."""
        order = [k for k in ("damage onset", "largest deflection", "end") if k in self.snapshots]
        if snapshots and order:
            states = self._gathered([self.snapshots[k] for k in order])
            if states is not None:
                _snapshots_png(list(zip(order, states)), Path(out_dir) / SNAPSHOTS)
        if self.frames:
            frames = self._gathered(self.frames)
            if frames is not None:
                _animation_gif(frames, Path(out_dir) / ANIMATION)


def _grid(quads: np.ndarray, alpha: np.ndarray, live: np.ndarray):
    import pyvista

    q = quads[live]
    n = q.shape[0]
    cells = np.hstack([np.full((n, 1), 4), np.arange(4 * n).reshape(n, 4)]).ravel()
    grid = pyvista.UnstructuredGrid(cells, np.full(n, 9, dtype=np.uint8), q.reshape(-1, 3))  # 9 = VTK_QUAD
    grid.cell_data["SDV2"] = alpha[live]
    return grid


def _renderer(window=(640, 560)):
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista

    pyvista.OFF_SCREEN = True
    return pyvista.Plotter(off_screen=True, window_size=window)


def _render(states, window=(640, 560)) -> tuple[list[np.ndarray], float]:
    """One image per state, all with the same camera (looking at the fabric's underside from
    below and aside, parallel projection); returns the images and metres per pixel."""
    all_pts = np.concatenate([s[2][s[4]].reshape(-1, 3) for s in states if s[4].any()] or [np.zeros((1, 3))])
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo)) or 1.0
    images = []
    scale = None
    for _, _, quads, alpha, live in states:
        p = _renderer(window)
        if live.any():
            p.add_mesh(_grid(quads, alpha, live), scalars="SDV2", cmap="viridis", clim=(0.0, 1.0),
                       show_scalar_bar=False, ambient=0.45, diffuse=0.6)
        p.enable_parallel_projection()
        p.camera.focal_point = centre
        p.camera.position = centre + radius * np.array([0.55, -1.1, -0.75])
        p.camera.up = (0.0, 0.0, 1.0)
        p.camera.parallel_scale = 0.62 * radius
        images.append(p.screenshot(return_img=True))
        scale = 2 * p.camera.parallel_scale / window[1]
        p.close()
    return images, scale


def _snapshots_png(named_states, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    images, m_per_px = _render([s for _, s in named_states])
    fig, axes = plt.subplots(1, len(images), figsize=(4.3 * len(images) + 1.0, 4.2), squeeze=False)
    bar = _scale_bar_length(m_per_px * images[0].shape[1])
    for ax, img, (name, (t, d, *_)) in zip(axes[0], images, named_states):
        ax.imshow(img)
        ax.set_title(f"{name}\nt = {t * 1e6:.0f} us, central deflection {d * 1e3:.1f} mm", fontsize=9)
        ax.axis("off")
        h, w = img.shape[:2]
        px = bar / m_per_px
        ax.plot([0.05 * w, 0.05 * w + px], [0.93 * h, 0.93 * h], "k-", lw=3)
        ax.text(0.05 * w + px / 2, 0.9 * h, f"{bar * 1e3:g} mm", ha="center", va="bottom", fontsize=8)
    fig.colorbar(ScalarMappable(Normalize(0.0, 1.0), "viridis"), ax=list(axes[0]), shrink=0.8,
                 label="warp integrity alpha1 (SDV2)")
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)


def _scale_bar_length(width_m: float) -> float:
    """A round length (1, 2 or 5 x 10^k m) near a fifth of the picture's width."""
    target = width_m / 5
    k = np.floor(np.log10(target))
    return float(min((f * 10 ** k for f in (1, 2, 5, 10)), key=lambda x: abs(x - target)))


def _animation_gif(frames, path: Path) -> None:
    from PIL import Image

    images, _ = _render(frames, window=(480, 420))
    pil = [Image.fromarray(np.asarray(img)[..., :3]) for img in images]
    pil[0].save(path, save_all=True, append_images=pil[1:], duration=120, loop=0)
