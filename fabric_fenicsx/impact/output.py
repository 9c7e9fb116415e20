"""Output of an impact run: XDMF time series, history.csv, summary.json and PNG pictures.

* ``impact.xdmf`` (+ ``.h5``): nodal ``displacement`` and ``velocity`` (3 components) and the
  cell-wise fields P1, P2 (N/m), E1, E2 and SDV1-3 (Table 2) as area-weighted averages of the
  quadrature points of each cell (XDMF cannot hold quadrature data). A removed cell
  (deleted or eroded) has SDV1 = 0 and P1 = P2 = 0: in ParaView, Threshold on SDV1 > 0 shows
  the holes. Only the fields the scene lists are written, at the scene's interval.
* ``history.csv``: one row per history interval, written while the run goes (rank 0).
* ``summary.json``: the run's summary (rank 0).
* ``velocity_history.png`` (projectile velocity and contact force against time) and
  ``damage_map.png`` (final SDV1, SDV2, SDV3 on the reference fabric, holes left blank),
  rendered off-screen with matplotlib and pyvista.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
from dolfinx import fem, io
from mpi4py import MPI

__all__ = ["ImpactOutput", "cell_average"]

CELL_FIELDS = ("P1", "P2", "E1", "E2", "SDV1", "SDV2", "SDV3")
_QUAD_CYCLE = np.array([0, 1, 3, 2])  # DOLFINx tensor-product vertex order -> perimeter order


def cell_average(values: np.ndarray, weights: np.ndarray, n_points_per_cell: int) -> np.ndarray:
    """Area-weighted average per cell of a point field (cell-major point layout)."""
    w = weights.reshape(-1, n_points_per_cell)
    return (w * np.asarray(values).reshape(-1, n_points_per_cell)).sum(axis=1) / w.sum(axis=1)


def _json_default(x):
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


class ImpactOutput:
    """Writers for one run. Collective: construct, ``frame`` and ``finish`` on every rank."""

    def __init__(self, out_dir: Path, membrane, fields: list[str], comm: MPI.Comm,
                 history_columns: tuple[str, ...]):
        self.out_dir = Path(out_dir)
        self.comm = comm
        self.rank0 = comm.rank == 0
        self.m = membrane
        self.fields = list(fields)
        if self.rank0:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        comm.barrier()
        self.columns = history_columns
        self.history_rows: list[list[float]] = []
        self._csv = None
        if self.rank0:
            self._csv_file = open(self.out_dir / "history.csv", "w", newline="")
            self._csv = csv.writer(self._csv_file)
            self._csv.writerow(history_columns)
        self.xdmf_path = None
        self._xdmf = None
        if self.fields:
            self.xdmf_path = self.out_dir / "impact.xdmf"
            self._xdmf = io.XDMFFile(comm, str(self.xdmf_path), "w")
            self._xdmf.write_mesh(membrane.msh)
            self._nodal = {name: fem.Function(membrane.V, name=name)
                           for name in ("displacement", "velocity") if name in self.fields}
            W = fem.FunctionSpace(membrane.msh, ("DG", 0))
            self._cell_dofs = W.dofmap.list.array[:membrane.n_cells]
            self._cell = {name: fem.Function(W, name=name) for name in CELL_FIELDS if name in self.fields}

    # ------------------------------------------------------------------ while running
    def history(self, row: dict) -> None:
        values = [float(row[c]) for c in self.columns]
        if self.rank0:
            self.history_rows.append(values)
            self._csv.writerow([f"{v:.10g}" for v in values])
            self._csv_file.flush()

    def frame(self, t: float, u_owned: np.ndarray, v_owned: np.ndarray, point_fields: dict,
              live_cells: np.ndarray) -> None:
        """Write one XDMF frame at time t (collective)."""
        if self._xdmf is None:
            return
        n = self.m.n_owned_dofs
        for name, values in (("displacement", u_owned), ("velocity", v_owned)):
            f = self._nodal.get(name)
            if f is not None:
                f.x.array[:n] = values
                f.x.scatter_forward()
                self._xdmf.write_function(f, t)
        for name, f in self._cell.items():
            avg = cell_average(point_fields[name], self.m.quadrature_weights_detJ, self.m.n_points_per_cell)
            if name in ("SDV1", "P1", "P2"):
                avg = np.where(live_cells, avg, 0.0)
            f.x.array[self._cell_dofs] = avg
            f.x.scatter_forward()
            self._xdmf.write_function(f, t)

    # ------------------------------------------------------------------ at the end
    def finish(self, summary: dict, live_cells: np.ndarray, point_fields: dict, png: bool) -> None:
        """summary.json and (optionally) the PNG pictures (collective)."""
        if self.rank0:
            (self.out_dir / "summary.json").write_text(json.dumps(summary, indent=1, default=_json_default))
        if png:
            self._pictures(summary, live_cells, point_fields)

    def _pictures(self, summary: dict, live_cells: np.ndarray, point_fields: dict) -> None:
        m = self.m
        dofs = m.V.dofmap.list.array.reshape(-1, 4)[:m.n_cells][:, _QUAD_CYCLE]
        X = m.V.tabulate_dof_coordinates()
        quads = X[dofs]  # (n_cells, 4, 3) reference corners in perimeter order
        values = {k: cell_average(point_fields[k], m.quadrature_weights_detJ, m.n_points_per_cell)
                  for k in ("SDV1", "SDV2", "SDV3")}
        values["SDV1"] = np.where(live_cells, values["SDV1"], 0.0)
        gathered = self.comm.gather((quads, live_cells, values), root=0)
        if not self.rank0:
            return
        self._velocity_plot(summary)
        self._damage_map(gathered, summary)

    def _velocity_plot(self, summary: dict) -> None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        if not self.history_rows:
            return
        h = np.array(self.history_rows)
        col = {c: i for i, c in enumerate(self.columns)}
        t = h[:, col["time"]] * 1e6
        fig, ax = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        ax[0].plot(t, h[:, col["projectile_velocity"]], "k-")
        ax[0].set_ylabel("projectile velocity (m/s)")
        ax[0].axhline(0.0, color="0.7", lw=0.8)
        ax[0].set_title(f"{Path(str(summary.get('scene', ''))).stem}: v0 = {summary['v0']:g} m/s, "
                        f"residual {summary['residual_velocity']:.2f} m/s ({summary['end_reason']})")
        ax[1].plot(t, h[:, col["contact_force"]] * 1e-3, "b-", lw=0.8)
        ax[1].set_ylabel("contact force (kN)")
        ax[1].set_xlabel("time (us)")
        fig.tight_layout()
        fig.savefig(self.out_dir / "velocity_history.png", dpi=110)
        plt.close(fig)

    def _damage_map(self, gathered, summary: dict) -> None:
        import os

        if not os.environ.get("DISPLAY"):
            os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        import pyvista

        pyvista.OFF_SCREEN = True
        quads = np.concatenate([g[0] for g in gathered])
        live = np.concatenate([g[1] for g in gathered])
        values = {k: np.concatenate([g[2][k] for g in gathered]) for k in ("SDV1", "SDV2", "SDV3")}
        n = quads.shape[0]
        points = quads.reshape(-1, 3)
        cells = np.hstack([np.full((n, 1), 4), np.arange(4 * n).reshape(n, 4)]).ravel()
        grid = pyvista.UnstructuredGrid(cells, np.full(n, 9, dtype=np.uint8), points)  # 9 = VTK_QUAD
        for k, v in values.items():
            grid.cell_data[k] = v
        grid = grid.extract_cells(np.flatnonzero(live)) if not live.all() else grid
        plotter = pyvista.Plotter(shape=(1, 3), off_screen=True, window_size=(1500, 560))
        titles = {"SDV1": "SDV1 (0: both yarns broken / removed)", "SDV2": "SDV2 = alpha1 (warp)",
                  "SDV3": "SDV3 = alpha2 (fill)"}
        for j, k in enumerate(("SDV1", "SDV2", "SDV3")):
            plotter.subplot(0, j)
            if grid.n_cells:
                # No scalar bar: VTK's bar formats its labels with std::regex, which aborts
                # when DOLFINx (another libstdc++ ABI user) was imported first.
                plotter.add_mesh(grid.copy(), scalars=k, clim=(0.0, 1.0), cmap="viridis",
                                 show_edges=False, show_scalar_bar=False)
            plotter.add_text(titles[k] + "\npurple 0 ... yellow 1, blank = removed", font_size=9)
            plotter.view_xy()
        plotter.screenshot(str(self.out_dir / "damage_map.png"))
        plotter.close()

    def close(self) -> None:
        if self._xdmf is not None:
            self._xdmf.close()
            self._xdmf = None
        if self._csv is not None:
            self._csv_file.close()
            self._csv = None
