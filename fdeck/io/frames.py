"""Frame series that ParaView opens: VTU files + a PVD index, or one HDF5 file + an XDMF 3 index.

Both writers share one interface::

    series = VtuSeries(out_dir, "plate", points, {"hexahedron": conn_hex, "quad": conn_quad})
    series.write(t, point_data={"displacement": u, "velocity": v}, cell_data={"stress": s})
    ...
    series.close()

Conventions (both formats)
--------------------------
* ``points`` (n_node, 3) float64: the REFERENCE coordinates, written once per series (XDMF) or into every VTU. The
  caller passes the point field ``"displacement"`` (n_node, 3) and the user applies ParaView's *Warp By Vector* to
  see the deformed shape: the reference mesh stays the one the deck described and warping can be scaled. When the
  deformed coordinates are wanted directly, ``write(..., points=x)`` with x (n_node, 3) overrides the coordinates of
  that one frame (then do not also warp).
* ``cells``: ``{vtk_type: conn (n_el, k) int, 0-based}``, types from ``CELL_TYPES`` (``"hexahedron"``, ``"quad"``,
  ``"triangle"``, ``"tetra"``, ``"wedge"``, ``"line"``), node order as VTK. Several blocks make a mixed mesh; the
  cells are numbered block after block in the dict's order, and every cell field is one array (n_el_total, ...)
  concatenated in that same order.
* Fields: (n,) scalar, (n, 3) vector, (n, 6) symmetric tensor, (n, 3, 3) full tensor (stored as (n, 9), row-major),
  any other (n, m) a plain m-component array. Floating arrays are written as float64 (float32 stays float32),
  integer arrays as int64 (int32 stays int32). Values are written as given, in the model's units (fdeck: mm, N,
  MPa, s). A name may not be used for both a point and a cell field, and may not contain ``/`` or ``:``.
* Symmetric tensors: pass (n, 6) with components in the order ``XX YY ZZ XY YZ XZ`` (``TENSOR6_COMPONENTS``); every
  (n, 6) field is taken to be one.
  VTU: written unchanged as one 6-component array. This is VTK's symmetric-tensor order and ParaView labels the
  components of every 6-component array XX, YY, ZZ, XY, YZ, XZ, so the names shown are right.
  XDMF: written as the full symmetric 3x3 tensor, (n, 9) row-major XX XY XZ YX YY YZ ZX ZY ZZ, AttributeType
  "Tensor" (``sym6_to_full9``). Not "Tensor6", because ParaView's XDMF readers disagree on it: the XDMF 3 readers
  keep the 6 values in file order (labelled XX YY ZZ XY YZ XZ) while the legacy "XDMF Reader" expands them to 9
  assuming XDMF's order XX XY XZ YY YZ ZZ; no single 6-value order is right in both. "Matrix" keeps 6 values in
  the XDMF 3 readers but the legacy one reads the whole (n, 6) as ONE tuple. A 9-component "Tensor" comes through
  as the same 9 values, which ParaView labels XX XY XZ YX ... ZZ, in every reader and in meshio (legacy reader
  checked with VTK 9.7's ``vtkXdmfReader``; the XDMF 3 reader's source keeps a 9-value Tensor as is). It costs
  1.5x the storage of the tensor fields.
  meshio cannot write VTK's per-array ``ComponentName`` attributes, so for readers without ParaView's labels
  ``split_tensors=True`` also writes each component as a scalar ``<name>_XX``, ... (both formats; costs another
  1x the tensor storage, hence off by default).
* Times are float seconds, strictly increasing from frame to frame (two frames at one time are ambiguous to
  ParaView's time controls; it is an error, not something to paper over).

Moving surfaces (rigid tools)
-----------------------------
``write(..., surfaces=[(part, points (n, 3), triangles (m, 3) int), ...])`` adds triangulated surfaces (the
``Effect.surfaces()`` of the run's tools) to the frame, each as its own block, in current coordinates [mm]:
VTU: one more file ``<name>_<part>_<k:05d>.vtu`` per surface and frame, listed in the same ``.pvd`` at the same
time with ``part="i"`` (the blank is part 0, surfaces 1, 2, ... in order of first appearance), so ParaView's PVD
reader shows blank and tools as one multiblock data set. XDMF: one more temporal collection per surface in the same
``.xdmf`` (HDF5 ``/surfaces/<part>/<k:05d>/points`` and ``/triangles``), written *before* the blank's collection so
that readers taking one collection (meshio's ``TimeSeriesReader`` takes the last) still read the blank.

Crash safety
------------
Frame ``k`` appears in the index (``.pvd`` / ``.xdmf``) only after its data is complete on disk, and the index is
replaced atomically (temporary file + ``os.replace``), so a run killed with SIGKILL at any moment leaves an index
whose every frame is readable. VTU frames are themselves written to a temporary file and renamed. The HDF5 file is
opened in append mode, written and *closed* every frame, so between frames it is fully consistent; a kill *during*
the few milliseconds of an HDF5 append can in principle damage HDF5's metadata (HDF5 has no journal; this is the
residual risk of the one-file layout, absent from the VTU series). The file is created with HDF5's default
(earliest) format: files of the newer format that were not closed refuse to open until ``h5clear`` is run.
HDF5 file locking is disabled for the writer so that ParaView holding the file open does not stop the run.

Creating a series truncates an earlier series of the same name in ``out_dir``: its index is replaced by an empty
one, its ``.h5`` recreated, and its old ``<name>_NNNNN.vtu`` frames removed (so a shorter rerun never mixes frames
with a longer earlier run).
"""

from __future__ import annotations

import abc
import math
import os
import re
import secrets
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

import h5py
import meshio
import numpy as np

from fdeck.io.summary import atomic_write_text

__all__ = ["CELL_TYPES", "TENSOR6_COMPONENTS", "VtuSeries", "XdmfSeries", "open_series", "sym6_to_full9"]

#: Supported cell types: VTK/meshio name -> (nodes per cell, XDMF TopologyType, XDMF "Mixed" type id).
CELL_TYPES: dict[str, tuple[int, str, int]] = {
    "line": (2, "Polyline", 2),
    "triangle": (3, "Triangle", 4),
    "quad": (4, "Quadrilateral", 5),
    "tetra": (4, "Tetrahedron", 6),
    "wedge": (6, "Wedge", 8),
    "hexahedron": (8, "Hexahedron", 9),
}

#: Component order of a (n, 6) symmetric tensor; ParaView's default labels for 6-component arrays.
TENSOR6_COMPONENTS: tuple[str, ...] = ("XX", "YY", "ZZ", "XY", "YZ", "XZ")

# Column of the 6-vector holding each entry of the row-major 3x3: XX XY XZ / YX YY YZ / ZX ZY ZZ.
_SYM6_TO_FULL9 = np.array([0, 3, 5, 3, 1, 4, 5, 4, 2])


def sym6_to_full9(a: np.ndarray) -> np.ndarray:
    """(n, 6) symmetric tensors in XX YY ZZ XY YZ XZ order -> (n, 9) full tensors, row-major (XX XY XZ YX ... ZZ)."""
    return np.ascontiguousarray(np.asarray(a)[:, _SYM6_TO_FULL9])

# Series names become file names (one path component) and appear in XDMF "file.h5:/path" references, which
# readers split at ":".
_BAD_NAME_CHARS = re.compile(r'[/\\:\x00-\x1f]')


# --------------------------------------------------------------------------------------------------------------------
# validation shared by both writers


def _check_points(points, n_node: int | None = None) -> np.ndarray:
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must be (n_node, 3), got shape {pts.shape}")
    if n_node is not None and pts.shape[0] != n_node:
        raise ValueError(f"points override has {pts.shape[0]} nodes, the series has {n_node}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points contain NaN or inf")
    return pts


def _check_cells(cells: Mapping[str, np.ndarray], n_node: int) -> list[tuple[str, np.ndarray]]:
    if not cells:
        raise ValueError("cells must hold at least one block")
    blocks = []
    for ctype, conn in cells.items():
        if ctype not in CELL_TYPES:
            raise ValueError(f"unsupported cell type {ctype!r}; supported: {sorted(CELL_TYPES)}")
        conn = np.asarray(conn)
        k = CELL_TYPES[ctype][0]
        if conn.ndim != 2 or conn.shape[1] != k:
            raise ValueError(f"{ctype} connectivity must be (n_el, {k}), got shape {conn.shape}")
        if conn.size and conn.dtype.kind not in "iu":
            raise ValueError(f"{ctype} connectivity must be integer, got {conn.dtype}")
        conn = np.ascontiguousarray(conn, dtype=np.int64)
        if conn.size and (conn.min() < 0 or conn.max() >= n_node):
            bad = np.flatnonzero(np.any((conn < 0) | (conn >= n_node), axis=1))
            raise ValueError(f"{ctype} cells {bad[:10].tolist()} reference nodes outside 0..{n_node - 1}")
        blocks.append((ctype, conn))
    return blocks


def _check_name(name: str) -> str:
    if (
        not isinstance(name, str)
        or not name
        or name != name.strip()
        or name.startswith(".")
        or _BAD_NAME_CHARS.search(name)
    ):
        raise ValueError(
            f"series name {name!r} must be a plain file name: not empty, not starting with '.', no surrounding "
            "spaces, no '/', '\\', ':' or control characters"
        )
    return name


def _field_array(name: str, arr, n: int, where: str) -> np.ndarray:
    """Normalise one field to a C-contiguous (n,) or (n, m) array of float64/float32/int64/int32."""
    if not isinstance(name, str) or not name.strip() or "/" in name or ":" in name:
        raise ValueError(f"{where} field name {name!r} must be non-empty without '/' or ':'")
    a = np.asarray(arr)
    if a.dtype.kind == "f":
        a = a if a.dtype == np.float32 else a.astype(np.float64, copy=False)
    elif a.dtype.kind in "iub":
        a = a if a.dtype == np.int32 else a.astype(np.int64, copy=False)
    else:
        raise TypeError(f"{where} field {name!r} has unsupported dtype {a.dtype}")
    if a.ndim == 0 or a.shape[0] != n:
        raise ValueError(f"{where} field {name!r} has shape {a.shape}, expected first dimension {n}")
    if a.ndim == 3 and a.shape[1:] == (3, 3):
        a = a.reshape(n, 9)
    elif a.ndim == 2 and a.shape[1] == 1:
        a = a.reshape(n)
    elif a.ndim > 2:
        raise ValueError(f"{where} field {name!r} has shape {a.shape}: expected (n,), (n, m) or (n, 3, 3)")
    return np.ascontiguousarray(a)


def _fields(data: Mapping[str, np.ndarray] | None, n: int, where: str, split: bool) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name, arr in (data or {}).items():
        a = _field_array(name, arr, n, where)
        out[name] = a
        if split and a.ndim == 2 and a.shape[1] == 6:
            for j, comp in enumerate(TENSOR6_COMPONENTS):
                sub = f"{name}_{comp}"
                if sub in data:
                    raise ValueError(f"{where} field {sub!r} clashes with the split of tensor {name!r}")
                out[sub] = np.ascontiguousarray(a[:, j])
    return out


def _check_surfaces(surfaces) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """Validate [(part, points (n, 3), triangles (m, 3))] -> same with contiguous float64 / int64 arrays."""
    out, seen = [], set()
    for part, points, triangles in surfaces or ():
        part = _check_name(part)
        if part in seen:
            raise ValueError(f"surface {part!r} given twice in one frame")
        seen.add(part)
        pts = _check_points(points)
        (_, tri), = _check_cells({"triangle": triangles}, len(pts))
        out.append((part, pts, tri))
    return out


def _write_vtu_atomic(path: Path, mesh: meshio.Mesh, compression) -> None:
    """meshio VTU (binary, UInt64 headers) to a temporary file renamed to ``path``: complete or absent."""
    tmp = path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        # UInt64 block headers: VTK's default UInt32 caps one (compressed) array at 4 GiB.
        meshio.write(tmp, mesh, file_format="vtu", binary=True, compression=compression, header_type="UInt64")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


class _Series(abc.ABC):
    """Validation and bookkeeping common to both writers; subclasses implement ``_write_frame``."""

    def __init__(self, out_dir, name: str, points, cells, *, split_tensors: bool = False):
        self.out_dir = Path(out_dir)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self.name = _check_name(name)
        self.points = _check_points(points)
        self.n_node = self.points.shape[0]
        self.blocks = _check_cells(cells, self.n_node)
        self.block_sizes = [len(conn) for _, conn in self.blocks]
        self.n_cell = int(sum(self.block_sizes))
        self.split_tensors = bool(split_tensors)
        self.times: list[float] = []
        self._closed = False

    @property
    def n_frames(self) -> int:
        return len(self.times)

    def write(self, time: float, point_data=None, cell_data=None, points=None, surfaces=None) -> Path:
        """Write one frame and update the index; return the path of the index file.

        time        float [s], finite, greater than the previous frame's.
        point_data  {name: (n_node,) | (n_node, m) | (n_node, 3, 3)}, e.g. "displacement" (n_node, 3).
        cell_data   {name: (n_cell_total, ...)} concatenated over the cell blocks in ``cells`` order,
                    e.g. "stress" (n_cell_total, 6) in XX YY ZZ XY YZ XZ order.
        points      optional (n_node, 3) coordinates replacing the reference ones for this frame only.
        surfaces    optional [(part name, points (n, 3) [mm], triangles (m, 3) int 0-based), ...]: moving surfaces
                    (rigid tools) written beside the mesh in this frame (module docstring).
        """
        if self._closed:
            raise RuntimeError(f"series {self.name!r} is closed")
        t = float(time)
        if not math.isfinite(t):
            raise ValueError(f"frame time {time!r} is not finite")
        if self.times and t <= self.times[-1]:
            raise ValueError(f"frame time {t!r} does not follow the previous frame's {self.times[-1]!r}")
        pd = _fields(point_data, self.n_node, "point", self.split_tensors)
        cd = _fields(cell_data, self.n_cell, "cell", self.split_tensors)
        both = sorted(set(pd) & set(cd))
        if both:
            raise ValueError(f"field names used for both points and cells: {both}")
        pts = None if points is None else _check_points(points, self.n_node)
        surfs = _check_surfaces(surfaces)
        index = self._write_frame(len(self.times), t, pd, cd, pts)
        for part, spts, tri in surfs:
            self._write_surface(len(self.times), t, part, spts, tri)
        if surfs:
            self._write_index()
        self.times.append(t)
        return index

    @abc.abstractmethod
    def _write_frame(self, k, t, pd, cd, pts) -> Path:
        """Write frame k at time t (point and cell fields, optional moved points); return the frame's file."""

    @abc.abstractmethod
    def _write_surface(self, k, t, part, points, triangles) -> None:
        """Write surface ``part`` of frame k (after the frame's mesh); the caller then rewrites the index."""

    @abc.abstractmethod
    def _write_index(self) -> None:
        """Replace the index file (atomically) by one listing every frame written so far."""

    def close(self) -> None:
        """Finish the series (idempotent). Every frame is already complete on disk; this only forbids more."""
        self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _indent(elem: ET.Element, level: int) -> str:
    """Serialise ``elem`` indented as if it sat ``level`` levels deep, ending with a newline."""
    ET.indent(elem, space="  ", level=level)
    return "  " * level + ET.tostring(elem, encoding="unicode") + "\n"


# --------------------------------------------------------------------------------------------------------------------
# VTU + PVD


class VtuSeries(_Series):
    """``<name>_<k:05d>.vtu`` frames (meshio, binary, zlib-compressed) listed with their times in ``<name>.pvd``.

    Every frame is a complete unstructured grid (points, cells, fields), so each can be opened alone. Open the
    ``.pvd`` in ParaView for the time series.

    Parameters
    ----------
    out_dir        folder for all files (created if missing).
    name           series name, a plain file name (e.g. the deck's stem) without ``/``, ``\\`` or ``:``.
    points         (n_node, 3) float64 reference coordinates [mm].
    cells          {vtk_type: (n_el, k) int connectivity, 0-based}, blocks in output order.
    split_tensors  also write each (n, 6) field's components as scalars ``<name>_XX`` ... (default off).
    compression    "zlib" (default), "lzma" or None.
    """

    def __init__(self, out_dir, name, points, cells, *, split_tensors: bool = False, compression: str | None = "zlib"):
        super().__init__(out_dir, name, points, cells, split_tensors=split_tensors)
        self.compression = compression
        self.pvd_path = self.out_dir / f"{self.name}.pvd"
        self.files: list[Path] = []
        self._entries: list[str] = []
        self._parts: dict[str, int] = {}  # surface name -> PVD part number (the mesh is part 0)
        stale = re.compile(rf"^{re.escape(self.name)}_\d{{5,}}\.vtu$")
        for p in self.out_dir.iterdir():
            if stale.match(p.name):
                p.unlink()
        self._write_pvd()

    def _frame_path(self, k: int) -> Path:
        return self.out_dir / f"{self.name}_{k:05d}.vtu"

    def _write_frame(self, k, t, pd, cd, pts) -> Path:
        # Split the concatenated cell fields back into meshio's one-array-per-block form.
        bounds = np.cumsum([0] + self.block_sizes)
        cell_data = {n: [a[bounds[b] : bounds[b + 1]] for b in range(len(self.blocks))] for n, a in cd.items()}
        mesh = meshio.Mesh(
            self.points if pts is None else pts,
            [(ctype, conn) for ctype, conn in self.blocks],
            point_data=pd,
            cell_data=cell_data,
        )
        path = self._frame_path(k)
        _write_vtu_atomic(path, mesh, self.compression)  # the frame appears complete or not at all
        self.files.append(path)
        entry = ET.Element("DataSet", timestep=repr(t), group="", part="0", file=path.name)
        self._entries.append(_indent(entry, 2))
        self._write_pvd()  # only now does the index name the frame
        return self.pvd_path

    def _write_surface(self, k, t, part, points, triangles) -> None:
        if part not in self._parts:
            self._parts[part] = len(self._parts) + 1
            stale = re.compile(rf"^{re.escape(self.name)}_{re.escape(part)}_\d{{5,}}\.vtu$")
            for p in self.out_dir.iterdir():  # frames of this surface left by an earlier run of the same name
                if stale.match(p.name):
                    p.unlink()
        path = self.out_dir / f"{self.name}_{part}_{k:05d}.vtu"
        _write_vtu_atomic(path, meshio.Mesh(points, [("triangle", triangles)]), self.compression)
        self.files.append(path)
        entry = ET.Element("DataSet", timestep=repr(t), group="", part=str(self._parts[part]), file=path.name)
        self._entries.append(_indent(entry, 2))

    def _write_index(self) -> None:
        self._write_pvd()

    def _write_pvd(self) -> None:
        text = (
            '<?xml version="1.0"?>\n'
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
            "  <Collection>\n" + "".join(self._entries) + "  </Collection>\n</VTKFile>\n"
        )
        atomic_write_text(self.pvd_path, text)


# --------------------------------------------------------------------------------------------------------------------
# XDMF 3 + HDF5


def _data_item(h5_name: str, h5_path: str, arr_shape: tuple[int, ...], dtype: np.dtype) -> ET.Element:
    kind = {"f": "Float", "i": "Int", "u": "UInt"}[dtype.kind]
    item = ET.Element(
        "DataItem",
        Dimensions=" ".join(str(d) for d in arr_shape),
        DataType=kind,
        Precision=str(dtype.itemsize),
        Format="HDF",
    )
    item.text = f"{h5_name}:{h5_path}"
    return item


def _attribute_type(a: np.ndarray) -> str:
    if a.ndim == 1:
        return "Scalar"
    # (n, 6) never gets here: it is written as a full (n, 9) "Tensor" (module docstring: Tensor6 is ambiguous).
    return {3: "Vector", 9: "Tensor"}.get(a.shape[1], "Matrix")


class XdmfSeries(_Series):
    """One ``<name>.h5`` beside ``<name>.xdmf`` (XDMF 3): a temporal collection of uniform grids.

    HDF5 layout (all in ``out_dir``)::

        /mesh/points            (n_node, 3) float64   reference coordinates
        /mesh/topology          (n_el, k) int64       one cell type, or
                                (L,) int64            mixed: per cell [xdmf_type_id, (2 for lines), nodes...]
        /frames/<k:05d>         group, attribute "time" (float64)
        /frames/<k:05d>/<field> (n_node | n_cell, ...) one array per point or cell field
        /geometry/<k:05d>       (n_node, 3) float64   only for frames written with a ``points`` override

    Geometry and topology are written once, at creation. Each frame's uniform grid carries ``<Time Value>``, a
    Geometry and a Topology that reference the shared datasets (repeated as plain HDF references rather than XInclude
    or Reference items, which not every reader follows), and one Attribute per field with Center "Node"/"Cell" and
    AttributeType Scalar (n,), Vector (n,3), Tensor (n,9), else Matrix. A symmetric (n, 6) field is stored and
    declared as its full (n, 9) tensor (see the module docstring: "Tensor6" is read differently by ParaView's
    XDMF readers), so ``/frames/<k>/stress`` is (n_cell, 9).
    A mesh with several cell blocks uses one "Mixed" topology (cells in block order), which ParaView and meshio
    read as one grid with one cell-field array per field.

    Parameters are those of ``VtuSeries`` except ``compression``: here an HDF5 filter for the field datasets
    ("gzip", "lzf" or None, the default: gzip costs write time and most fields compress poorly).
    """

    def __init__(self, out_dir, name, points, cells, *, split_tensors: bool = False, compression: str | None = None):
        super().__init__(out_dir, name, points, cells, split_tensors=split_tensors)
        self.compression = compression
        self.h5_path = self.out_dir / f"{self.name}.h5"
        self.xdmf_path = self.out_dir / f"{self.name}.xdmf"
        self._grids: list[str] = []
        self._surface_grids: dict[str, list[str]] = {}  # surface name -> its uniform grids, one per frame

        if len(self.blocks) == 1:
            ctype, conn = self.blocks[0]
            topology = conn
            self._topology_attrs = {"TopologyType": CELL_TYPES[ctype][1], "NumberOfElements": str(self.n_cell)}
            if ctype == "line":
                self._topology_attrs["NodesPerElement"] = "2"
        else:
            parts = []
            for ctype, conn in self.blocks:
                k, _, type_id = CELL_TYPES[ctype]
                head = [type_id, 2] if ctype == "line" else [type_id]  # polylines also state their node count
                parts.append(np.hstack([np.tile(np.array(head, np.int64), (len(conn), 1)), conn]).ravel())
            topology = np.concatenate(parts)
            self._topology_attrs = {"TopologyType": "Mixed", "NumberOfElements": str(self.n_cell)}

        with self._open_h5("w") as f:
            f.attrs["writer"] = "fdeck.io.frames.XdmfSeries"
            f.attrs["cell_types"] = ",".join(ctype for ctype, _ in self.blocks)
            f.attrs["block_sizes"] = np.array(self.block_sizes, np.int64)
            f.create_dataset("mesh/points", data=self.points)
            f.create_dataset("mesh/topology", data=topology)
            f.create_group("frames")
        self._topology_shape = topology.shape
        self._write_xdmf()  # replaces any index of an earlier run that would point into the new, empty file

    def _open_h5(self, mode: str) -> h5py.File:
        # locking=False: a ParaView session holding the file open must not make the run fail at its next frame.
        return h5py.File(self.h5_path, mode, locking=False)

    def _write_frame(self, k, t, pd, cd, pts) -> Path:
        key = f"{k:05d}"
        with self._open_h5("a") as f:
            # Left over by an earlier write() of this frame that raised (disk full, ...): never listed, replace it.
            for stale in (f"frames/{key}", f"geometry/{key}"):
                if stale in f:
                    del f[stale]
            g = f.create_group(f"frames/{key}")
            g.attrs["time"] = t
            for fields in (pd, cd):
                for fname, a in fields.items():
                    if a.ndim == 2 and a.shape[1] == 6:
                        fields[fname] = a = sym6_to_full9(a)
                    g.create_dataset(fname, data=a, compression=self.compression)
            if pts is not None:
                f.create_dataset(f"geometry/{key}", data=pts)
        # The file is closed (everything flushed to the OS) before the index names the frame.
        h5 = self.h5_path.name
        grid = ET.Element("Grid", Name=f"frame_{key}", GridType="Uniform")
        ET.SubElement(grid, "Time", Value=repr(t))
        geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
        geo.append(_data_item(h5, "/mesh/points" if pts is None else f"/geometry/{key}", self.points.shape,
                              self.points.dtype))
        topo = ET.SubElement(grid, "Topology", **self._topology_attrs)
        topo.append(_data_item(h5, "/mesh/topology", self._topology_shape, np.dtype(np.int64)))
        for center, fields in (("Node", pd), ("Cell", cd)):
            for fname, a in fields.items():
                att = ET.SubElement(grid, "Attribute", Name=fname, AttributeType=_attribute_type(a), Center=center)
                att.append(_data_item(h5, f"/frames/{key}/{fname}", a.shape, a.dtype))
        self._grids.append(_indent(grid, 3))
        self._write_xdmf()
        return self.xdmf_path

    def _write_surface(self, k, t, part, points, triangles) -> None:
        key = f"{k:05d}"
        base = f"surfaces/{part}/{key}"
        with self._open_h5("a") as f:
            if base in f:  # left by an earlier write() of this frame that raised
                del f[base]
            f.create_dataset(f"{base}/points", data=points)
            f.create_dataset(f"{base}/triangles", data=triangles)
        h5 = self.h5_path.name
        grid = ET.Element("Grid", Name=f"{part}_{key}", GridType="Uniform")
        ET.SubElement(grid, "Time", Value=repr(t))
        geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
        geo.append(_data_item(h5, f"/{base}/points", points.shape, points.dtype))
        topo = ET.SubElement(grid, "Topology", TopologyType="Triangle", NumberOfElements=str(len(triangles)))
        topo.append(_data_item(h5, f"/{base}/triangles", triangles.shape, triangles.dtype))
        self._surface_grids.setdefault(part, []).append(_indent(grid, 3))

    def _write_index(self) -> None:
        self._write_xdmf()

    def _write_xdmf(self) -> None:
        # surfaces first: meshio's TimeSeriesReader reads the last temporal collection, which stays the mesh's
        collections = [(part, grids) for part, grids in self._surface_grids.items()] + [(self.name, self._grids)]
        text = (
            '<?xml version="1.0" encoding="utf-8"?>\n'
            '<Xdmf Version="3.0">\n'
            "  <Domain>\n"
            + "".join(f'    <Grid Name={quoteattr(name)} GridType="Collection" CollectionType="Temporal">\n'
                      + "".join(grids) + "    </Grid>\n" for name, grids in collections)
            + "  </Domain>\n</Xdmf>\n"
        )
        atomic_write_text(self.xdmf_path, text)


# --------------------------------------------------------------------------------------------------------------------

_WRITERS = {"vtu": VtuSeries, "xdmf": XdmfSeries}


def open_series(formats: Sequence[str], out_dir, name: str, points, cells, **options) -> list[_Series]:
    """One writer per format in ``formats`` (``"vtu"``, ``"xdmf"``), all over the same mesh and name.

    ``options`` (e.g. ``split_tensors=True``) go to every writer. Call ``write`` on each writer every frame.
    """
    formats = list(formats)
    unknown = [f for f in formats if f not in _WRITERS]
    if unknown:
        raise ValueError(f"unknown frame formats {unknown}; known: {sorted(_WRITERS)}")
    if len(set(formats)) != len(formats):
        raise ValueError(f"frame formats repeated: {formats}")
    return [_WRITERS[f](out_dir, name, points, cells, **options) for f in formats]
