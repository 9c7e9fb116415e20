"""Output of an impact run: run.json, XDMF time series, history.csv, summary.json, pictures.

One run owns its folder's output files (:data:`OWNED_FILES`). At start, rank 0 removes the
ones an earlier run left there (other files are left alone) and writes ``run.json`` first, with
a run id that ``summary.json`` repeats: a folder never mixes two runs' results.

* ``run.json``: run id, start time, host, process id, ranks, the scene and its settings;
  completed at the end with the end time and reason.
* ``impact.xdmf`` (+ ``impact.h5``): one unstructured grid per written time step carrying every
  requested field: nodal ``displacement`` and ``velocity`` (3 components, m and m/s) and the
  cell-wise P1, P2 (N/m), E1, E2 and SDV1-3 (Table 2) as area-weighted averages of the quadrature
  points of each cell (XDMF cannot hold quadrature data). The mesh is stored once in the HDF5
  file and every grid refers to it. A removed cell (deleted or eroded) has SDV1 = 0 and NaN in
  every other cell field, so colour scales over a run ignore it; Threshold SDV1 > 0 hides it.
  Readable as one dataset with a time series by VTK's ``vtkXdmfReader`` (ParaView's XDMF
  reader): :func:`read_run`.
* ``paraview_view.py``: the ParaView view of the run (``pvpython paraview_view.py``), a copy of
  :mod:`fabric_fenicsx.impact.paraview_view`.
* ``history.csv``: one row per history interval, written while the run goes (rank 0).
* ``removed_cells.csv``: one row per removed cell, gathered to rank 0 and written in the step
  that removed it (columns: :data:`~fabric_fenicsx.impact.removal_log.REMOVED_CELL_COLUMNS`).
* ``cracks.csv``: with ``material.failure = "yarn_crack"``, ``"yarn_tip"``, ``"yarn_strain"``, ``"shear_lag"``, ``"del_zone"`` or ``"del_zone_budget"``, one row per cell
  that joined a crack, written in the step it joined (columns:
  :data:`~fabric_fenicsx.fem.yarn_crack.CRACK_COLUMNS`).
* ``summary.json``: the run's summary with its run id (rank 0).
* ``velocity_history.png`` (projectile velocity and contact force against time) and
  ``damage_map.png`` (final SDV1, SDV2, SDV3 on the reference fabric, holes left blank) and
  ``damage.npz`` (the same as arrays: reference cell corners ``quads``, ``live``, ``SDV1-3``;
  and, where the material keeps them, ``E1_peak``, ``E2_peak``: each cell's largest warp and
  fill Green strain over the run while it was live, the largest over its points),
  rendered off-screen with matplotlib and pyvista.
"""

from __future__ import annotations

import csv
import datetime
import json
import os
import socket
import uuid
from pathlib import Path

import numpy as np
from mpi4py import MPI

from fabric_fenicsx.fem.yarn_crack import CRACK_COLUMNS, KINDS
from fabric_fenicsx.impact.removal_log import REMOVED_CELL_COLUMNS, RULES

__all__ = ["ImpactOutput", "XdmfSeries", "RunFrames", "read_run", "start_run", "cell_average",
           "OWNED_FILES", "NODAL_FIELDS", "CELL_FIELDS"]

NODAL_FIELDS = ("displacement", "velocity")
CELL_FIELDS = ("P1", "P2", "E1", "E2", "SDV1", "SDV2", "SDV3", "mu_crit1", "mu_crit2")
XDMF_NAME = "impact.xdmf"
DATA_NAME = "impact.bin"
H5_NAME = "impact.h5"  # written by earlier versions: removed like the others
REMOVED_NAME = "removed_cells.csv"
CRACKS_NAME = "cracks.csv"
VIEWER_NAME = "paraview_view.py"
OWNED_FILES = ("run.json", "history.csv", REMOVED_NAME, CRACKS_NAME, "summary.json", XDMF_NAME, DATA_NAME, H5_NAME, VIEWER_NAME,
               "velocity_history.png", "damage_map.png", "damage.npz", "snapshots.png", "impact.gif")
"""Every file an impact run writes into its folder; a new run removes them first."""

_QUAD_CYCLE = np.array([0, 1, 3, 2])  # DOLFINx tensor-product vertex order -> perimeter order


def cell_corners(V, n_cells: int) -> np.ndarray:
    """Local node indices of the first ``n_cells`` (owned) quadrilaterals of ``V``, each in
    perimeter order (the order VTK and a polygon take), shape (n_cells, 4)."""
    return V.dofmap.list.array.reshape(-1, 4)[:n_cells][:, _QUAD_CYCLE]


def cell_average(values: np.ndarray, weights: np.ndarray, n_points_per_cell: int) -> np.ndarray:
    """Area-weighted average per cell of a point field (cell-major point layout)."""
    w = weights.reshape(-1, n_points_per_cell)
    return (w * np.asarray(values).reshape(-1, n_points_per_cell)).sum(axis=1) / w.sum(axis=1)


def output_cell_fields(point_fields: dict, names, weights: np.ndarray, n_points_per_cell: int,
                       live_cells: np.ndarray) -> dict[str, np.ndarray]:
    """Cell averages of the named point fields; in a removed cell SDV1 = 0 and the state's fields
    NaN (the strength scatter's mu_crit1, mu_crit2, a property of the fabric, stay)."""
    out = {}
    for name in names:
        avg = cell_average(point_fields[name], weights, n_points_per_cell)
        out[name] = avg if name.startswith("mu_crit") else np.where(live_cells, avg, 0.0 if name == "SDV1" else np.nan)
    return out


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


def _now() -> str:
    return datetime.datetime.now().astimezone().isoformat(timespec="seconds")


def _write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=1, default=_json_default))


# ---------------------------------------------------------------------------------- run marker
def start_run(out_dir: Path, comm: MPI.Comm, info: dict | None = None) -> str:
    """Claim ``out_dir`` for a new run (collective): rank 0 creates it, removes the files an
    earlier run wrote there (:data:`OWNED_FILES`, nothing else) and writes ``run.json``.
    Returns the run id (time stamp, process id and a random part), the same on every rank."""
    out_dir = Path(out_dir)
    run_id = None
    if comm.rank == 0:
        run_id = f"{datetime.datetime.now():%Y%m%dT%H%M%S}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        out_dir.mkdir(parents=True, exist_ok=True)
        for name in OWNED_FILES:
            (out_dir / name).unlink(missing_ok=True)
        _write_json(out_dir / "run.json", {"run_id": run_id, "started": _now(), "host": socket.gethostname(),
                                           "pid": os.getpid(), "n_ranks": comm.size, **(info or {})})
    return comm.bcast(run_id, root=0)


# ---------------------------------------------------------------------------------- XDMF writer
_XDMF_HEAD = """<?xml version="1.0"?>
<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>
<Xdmf Version="3.0">
  <Domain>
    <Grid Name="fabric" GridType="Collection" CollectionType="Temporal">
"""
_XDMF_TAIL = """    </Grid>
  </Domain>
</Xdmf>
"""


def _data_item(dims: tuple[int, ...], number_type: str, precision: int, seek: int) -> str:
    """An XDMF DataItem for the array at byte offset ``seek`` of the data file."""
    d = " ".join(str(n) for n in dims)
    return (f'<DataItem Dimensions="{d}" NumberType="{number_type}" Precision="{precision}" '
            f'Format="Binary" Endian="Little" Seek="{seek}">{DATA_NAME}</DataItem>')


class XdmfSeries:
    """``impact.xdmf`` + ``impact.bin``: one unstructured grid per time step with every field.

    The heavy data are raw little-endian arrays appended to ``impact.bin`` (XDMF's "Binary"
    format: the XML gives each array's type, shape and byte offset); the mesh (reference
    coordinates and quadrilaterals) is written once and every frame's grid refers to it, each
    frame adds one float64 array per field. Under MPI the owned values are gathered to rank 0
    in DOLFINx's global numbering (owned nodes and cells in rank order) and rank 0 writes.
    The frame's grid is appended to the XML only after its data are flushed, so the XDMF file
    lists complete frames only and an interrupted run stays readable.

    V: the nodal (3-component P1) function space; n_cells: owned cells;
    nodal, cell: the names of the nodal and cell fields to write.
    """

    def __init__(self, out_dir: Path, V, n_cells: int, comm: MPI.Comm, nodal=(), cell=()):
        self.comm = comm
        self.rank0 = comm.rank == 0
        self.path = Path(out_dir) / XDMF_NAME
        self.nodal, self.cell = tuple(nodal), tuple(cell)
        self.times: list[float] = []
        imap = V.dofmap.index_map
        n_nodes = imap.size_local
        self._node_counts = np.array(comm.allgather(3 * n_nodes))
        self._cell_counts = np.array(comm.allgather(n_cells))
        self.n_nodes = int(self._node_counts.sum()) // 3
        self.n_cells = int(self._cell_counts.sum())
        nodes = cell_corners(V, n_cells)
        topology = imap.local_to_global(nodes.ravel()).astype(np.int64)
        coordinates = V.tabulate_dof_coordinates()[:n_nodes].ravel()
        self._data = self._xml = None
        if self.rank0:
            self._data = open(self.path.with_name(DATA_NAME), "wb")
            self._xml = open(self.path, "wb")
            self._xml.write(_XDMF_HEAD.encode())
            self._tail_at = self._xml.tell()
            self._xml.write(_XDMF_TAIL.encode())
            self._xml.flush()
        self._geometry_at = self._append(coordinates, self._node_counts)
        self._topology_at = self._append(topology, 4 * self._cell_counts)

    def _append(self, local: np.ndarray, counts: np.ndarray) -> int | None:
        """Gather the ranks' pieces of one array to rank 0 (collective), which appends it to
        the data file; returns its byte offset there (rank 0; None elsewhere)."""
        local = np.ascontiguousarray(local, dtype="<i8" if local.dtype.kind in "iu" else "<f8")
        whole = np.empty(int(counts.sum()), dtype=local.dtype) if self.rank0 else None
        if self.comm.size == 1:
            whole = local
        else:
            self.comm.Gatherv(local, (whole, counts) if self.rank0 else None, root=0)
        if not self.rank0:
            return None
        at = self._data.tell()
        whole.tofile(self._data)
        return at

    def write(self, t: float, nodal: dict[str, np.ndarray], cell: dict[str, np.ndarray]) -> bool:
        """Append the frame at time t (s) (collective): ``nodal`` holds the owned node values
        (3 per node, node-major), ``cell`` the owned cell values of the named fields. A frame at
        a time not after the last one is skipped (returns False)."""
        if self.times and t <= self.times[-1]:
            return False
        offsets = {name: self._append(nodal[name], self._node_counts) for name in self.nodal}
        offsets.update({name: self._append(cell[name], self._cell_counts) for name in self.cell})
        self.times.append(float(t))
        if self.rank0:
            self._data.flush()
            self._xml.seek(self._tail_at)
            self._xml.write(self._grid_xml(t, offsets).encode())
            self._tail_at = self._xml.tell()
            self._xml.write(_XDMF_TAIL.encode())
            self._xml.truncate()
            self._xml.flush()
        return True

    def _grid_xml(self, t: float, offsets: dict[str, int]) -> str:
        """The XML of one frame: the shared mesh and one attribute per field."""
        lines = ['      <Grid Name="fabric" GridType="Uniform">',
                 f'        <Time Value="{t:.17g}" />',
                 f'        <Topology TopologyType="Quadrilateral" NumberOfElements="{self.n_cells}" '
                 'NodesPerElement="4">',
                 f'          {_data_item((self.n_cells, 4), "Int", 8, self._topology_at)}',
                 '        </Topology>',
                 '        <Geometry GeometryType="XYZ">',
                 f'          {_data_item((self.n_nodes, 3), "Float", 8, self._geometry_at)}',
                 '        </Geometry>']
        for name in self.nodal:
            lines += [f'        <Attribute Name="{name}" AttributeType="Vector" Center="Node">',
                      f'          {_data_item((self.n_nodes, 3), "Float", 8, offsets[name])}',
                      '        </Attribute>']
        for name in self.cell:
            lines += [f'        <Attribute Name="{name}" AttributeType="Scalar" Center="Cell">',
                      f'          {_data_item((self.n_cells,), "Float", 8, offsets[name])}',
                      '        </Attribute>']
        lines.append('      </Grid>')
        return "\n".join(lines) + "\n"

    def close(self) -> None:
        """Close the data and XML files (rank 0)."""
        for f in (self._data, self._xml):
            if f is not None:
                f.close()
        self._data = self._xml = None


# ---------------------------------------------------------------------------------- reader
class RunFrames:
    """The frames of a run's ``impact.xdmf`` as pyvista grids, read with VTK's vtkXdmfReader.

    ``times``: the frame times (s); ``frames[i]`` (or iteration) gives the unstructured grid
    of frame i (reference coordinates as points; nodal displacement and velocity, cell fields
    as in the module docstring), a copy the caller may change.
    """

    def __init__(self, path: Path):
        import vtk

        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"no XDMF time series at {self.path}: the run wrote none "
                                    "(output.xdmf_interval = 0 or output.fields = []) or ran elsewhere")
        self._reader = vtk.vtkXdmfReader()
        self._reader.SetFileName(str(self.path))
        self._reader.UpdateInformation()
        info = self._reader.GetOutputInformation(0)
        key = vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS()
        self.times = np.array(info.Get(key) if info.Has(key) else [], dtype=float)

    def __len__(self) -> int:
        return len(self.times)

    def __getitem__(self, i: int):
        import pyvista

        t = self.times[i]
        self._reader.UpdateTimeStep(t)
        data = self._reader.GetOutputDataObject(0)
        if data is None or not data.IsA("vtkUnstructuredGrid"):
            kind = data.GetClassName() if data is not None else "nothing"
            raise ValueError(f"{self.path}: expected one unstructured grid per time step, the reader "
                             f"gives {kind} (a file from an older version of fabric_fenicsx?)")
        grid = pyvista.UnstructuredGrid()
        grid.deep_copy(data)
        return grid

    def __iter__(self):
        return (self[i] for i in range(len(self)))


def read_run(out_dir: str | os.PathLike) -> RunFrames:
    """The frames of the run in ``out_dir`` (its ``impact.xdmf``): see :class:`RunFrames`."""
    return RunFrames(Path(out_dir) / XDMF_NAME)


def viewer_script() -> str:
    """The source of the ParaView view written beside each run (``paraview_view.py``)."""
    return (Path(__file__).with_name("paraview_view.py")).read_text()


# ---------------------------------------------------------------------------------- the run's writers
class ImpactOutput:
    """Writers for one run. Collective: construct, ``frame`` and ``finish`` on every rank.

    Construction claims the folder (:func:`start_run`: stale output removed, ``run.json``
    written) before anything else is written. scene: the run's scene, recorded in run.json
    (optional; its settings reach run.json at the end in any case, from the summary).
    """

    def __init__(self, out_dir: Path, membrane, fields: list[str], comm: MPI.Comm,
                 history_columns: tuple[str, ...], scene=None):
        self.out_dir = Path(out_dir)
        self.comm = comm
        self.rank0 = comm.rank == 0
        self.m = membrane
        self.fields = list(fields)
        info = {"out_dir": str(self.out_dir.resolve()), "fields": self.fields}
        if scene is not None:
            info.update(scene=str(scene.source), settings=scene.to_dict())
        self.run_id = start_run(self.out_dir, comm, info)
        self.columns = history_columns
        self.history_rows: list[list[float]] = []
        self._csv = None
        if self.rank0:
            self._csv_file = open(self.out_dir / "history.csv", "w", newline="")
            self._csv = csv.writer(self._csv_file)
            self._csv.writerow(history_columns)
        self.removed_rows: list[np.ndarray] = []
        """Every rank's removed-cell rows so far (rank 0), as written to removed_cells.csv."""
        self._removed = None
        self._cracks = None
        if self.rank0:
            self._removed_file = open(self.out_dir / REMOVED_NAME, "w", newline="")
            self._removed = csv.writer(self._removed_file)
            self._removed.writerow(REMOVED_CELL_COLUMNS)
            self._removed_file.flush()
        self.xdmf_path = None
        self._series = None
        if self.fields:
            self.xdmf_path = self.out_dir / XDMF_NAME
            self._series = XdmfSeries(self.out_dir, membrane.V, membrane.n_cells, comm,
                                      [f for f in NODAL_FIELDS if f in self.fields],
                                      [f for f in CELL_FIELDS if f in self.fields])
            if self.rank0:
                (self.out_dir / VIEWER_NAME).write_text(viewer_script())

    # ------------------------------------------------------------------ while running
    def history(self, row: dict) -> None:
        values = [float(row[c]) for c in self.columns]
        if self.rank0:
            self.history_rows.append(values)
            self._csv.writerow([f"{v:.10g}" for v in values])
            self._csv_file.flush()

    def removed_cells(self, local_rows: np.ndarray) -> None:
        """Append this step's removed cells (this rank's rows of
        :data:`~fabric_fenicsx.impact.removal_log.REMOVED_CELL_COLUMNS`) to removed_cells.csv
        (collective: every rank calls it in a step where any rank removed cells; rank 0 writes
        the ranks' rows in rank order)."""
        gathered = self.comm.gather(np.asarray(local_rows, dtype=float), root=0)
        if not self.rank0:
            return
        rows = np.concatenate(gathered)
        self.removed_rows.append(rows)
        rule, cell = REMOVED_CELL_COLUMNS.index("rule"), REMOVED_CELL_COLUMNS.index("cell")
        for row in rows:
            self._removed.writerow([RULES[int(v)] if j == rule else str(int(v)) if j == cell else f"{v:.10g}"
                                    for j, v in enumerate(row)])
        self._removed_file.flush()

    def cracks(self, rows: np.ndarray) -> None:
        """Append cells that joined a crack (rows of
        :data:`~fabric_fenicsx.fem.yarn_crack.CRACK_COLUMNS`, codes for family and kind) to
        cracks.csv, opened at the first call (one rank: the rule that cracks runs on one)."""
        if self._cracks is None:
            self._cracks_file = open(self.out_dir / CRACKS_NAME, "w", newline="")
            self._cracks = csv.writer(self._cracks_file)
            self._cracks.writerow(CRACK_COLUMNS)
        for t, family, kind, cell, x, y, line in rows:
            self._cracks.writerow([f"{t:.10g}", ("warp", "fill")[int(family)], KINDS[int(kind)],
                                   str(int(cell)), f"{x:.10g}", f"{y:.10g}", f"{line:.10g}"])
        self._cracks_file.flush()

    def all_removed_cells(self) -> np.ndarray:
        """Every removed-cell row written so far (rank 0; an empty table elsewhere)."""
        return (np.concatenate(self.removed_rows) if self.removed_rows
                else np.zeros((0, len(REMOVED_CELL_COLUMNS))))

    def frame(self, t: float, u_owned: np.ndarray, v_owned: np.ndarray, point_fields: dict,
              live_cells: np.ndarray) -> None:
        """Write one XDMF frame at time t (collective); u_owned, v_owned: owned nodal dofs, the
        point fields at the owned quadrature points. A frame at the time of the last is skipped."""
        if self._series is None:
            return
        m = self.m
        nodal = {"displacement": u_owned, "velocity": v_owned}
        cell = output_cell_fields(point_fields, self._series.cell, m.quadrature_weights_detJ,
                                  m.n_points_per_cell, live_cells)
        self._series.write(t, nodal, cell)

    # ------------------------------------------------------------------ at the end
    def finish(self, summary: dict, live_cells: np.ndarray, point_fields: dict, png: bool) -> None:
        """summary.json (with the run id, which is also put into ``summary``), run.json
        completed, and (optionally) the PNG pictures (collective)."""
        summary["run_id"] = self.run_id
        if self.rank0:
            _write_json(self.out_dir / "summary.json", summary)
            self._complete_marker(summary)
        if png:
            self._pictures(summary, live_cells, point_fields)

    def _complete_marker(self, summary: dict) -> None:
        """run.json gains the end time and reason, and the settings if it lacked them."""
        path = self.out_dir / "run.json"
        marker = json.loads(path.read_text())
        marker.update(finished=_now(), end_reason=summary.get("end_reason"))
        marker.setdefault("scene", summary.get("scene"))
        marker.setdefault("settings", summary.get("settings"))
        _write_json(path, marker)

    def _pictures(self, summary: dict, live_cells: np.ndarray, point_fields: dict) -> None:
        m = self.m
        dofs = cell_corners(m.V, m.n_cells)
        X = m.V.tabulate_dof_coordinates()
        quads = X[dofs]  # (n_cells, 4, 3) reference corners in perimeter order
        values = {k: cell_average(point_fields[k], m.quadrature_weights_detJ, m.n_points_per_cell)
                  for k in ("SDV1", "SDV2", "SDV3", "mu_crit1") if k in point_fields}
        values["SDV1"] = np.where(live_cells, values["SDV1"], 0.0)
        peaks = {k: point_fields[k].reshape(-1, m.n_points_per_cell).max(axis=1)
                 for k in ("E1_peak", "E2_peak") if k in point_fields}
        gathered = self.comm.gather((quads, live_cells, values, peaks), root=0)
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
        quads = np.concatenate([g[0] for g in gathered])
        live = np.concatenate([g[1] for g in gathered])
        values = {k: np.concatenate([g[2][k] for g in gathered]) for k in gathered[0][2]}
        peaks = {k: np.concatenate([g[3][k] for g in gathered]) for k in gathered[0][3]}
        # the same final state as numbers, for pictures of several runs (fabric-fenicsx study)
        np.savez_compressed(self.out_dir / "damage.npz", quads=quads[:, :, :2], live=live, **values, **peaks)
        if not os.environ.get("DISPLAY"):
            os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        import pyvista

        pyvista.OFF_SCREEN = True
        n = quads.shape[0]
        points = quads.reshape(-1, 3)
        cells = np.hstack([np.full((n, 1), 4), np.arange(4 * n).reshape(n, 4)]).ravel()
        grid = pyvista.UnstructuredGrid(cells, np.full(n, 9, dtype=np.uint8), points)  # 9 = VTK_QUAD
        for k, v in values.items():
            grid.cell_data[k] = v
        grid = grid.extract_cells(np.flatnonzero(live)) if not live.all() else grid
        panels = list(values)   # SDV1..3, and the warp's critical stretch with a strength scatter
        plotter = pyvista.Plotter(shape=(1, len(panels)), off_screen=True,
                                  window_size=(500 * len(panels), 560))
        titles = {"SDV1": "SDV1 (0: both yarns broken / removed)", "SDV2": "SDV2 = alpha1 (warp)",
                  "SDV3": "SDV3 = alpha2 (fill)"}
        for j, k in enumerate(panels):
            plotter.subplot(0, j)
            if k == "mu_crit1":   # the field itself, every cell (removed ones too)
                lo, hi = float(values[k].min()), float(values[k].max())
                full = pyvista.UnstructuredGrid(cells, np.full(n, 9, dtype=np.uint8), points)
                full.cell_data[k] = values[k]
                plotter.add_mesh(full, scalars=k, clim=(lo, max(hi, lo + 1e-9)), cmap="magma",
                                 show_edges=False, show_scalar_bar=False)
                plotter.add_text(f"warp critical stretch (strength scatter)\n"
                                 f"black {lo:.4f} ... yellow {hi:.4f}", font_size=9)
            else:
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
        if self._series is not None:
            self._series.close()
            self._series = None
        if self._csv is not None:
            self._csv_file.close()
            self._csv = None
        if self._removed is not None:
            self._removed_file.close()
            self._removed = None
        if self._cracks is not None:
            self._cracks_file.close()
            self._cracks = None
