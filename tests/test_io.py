"""Writers in fdeck.io: frame series (VTU+PVD, XDMF+HDF5), history CSV, atomic JSON summary.

Tolerance for every round trip below: EXACT equality. VTU frames are written binary (base64 of the raw float64
bytes, zlib-compressed, lossless), HDF5 stores the raw float64 bytes, and the history CSV uses ``repr`` (the shortest
decimal that reads back to the same float64). Nothing is converted through text with fewer digits, so any
difference at all, even 1e-16 relative, would be a bug (a float32 cast, a reordering, a wrong block split).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

from fdeck.io.frames import TENSOR6_COMPONENTS, VtuSeries, XdmfSeries, open_series, sym6_to_full9
from fdeck.io.history import HistoryWriter, read_history
from fdeck.io.summary import atomic_write_text, write_json_atomic

pytestmark = pytest.mark.unit

REPO = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------------------------------------------------
# a small mesh: 2 hexahedra side by side, plus 2 quads on their top face (mixed case) and 1 triangle


def _mesh(mixed: bool):
    x = np.array([0.0, 1.0, 2.0])
    y = np.array([0.0, 1.0])
    z = np.array([0.0, 0.5])
    X = np.array([[xi, yi, zi] for zi in z for yi in y for xi in x], dtype=np.float64)  # node = i + 3 j + 6 k
    X += 1e-3 * np.sin(np.arange(X.size)).reshape(X.shape)  # non-round coordinates: exactness must be real
    n = lambda i, j, k: i + 3 * j + 6 * k  # noqa: E731
    hexes = np.array([[n(i, 0, 0), n(i + 1, 0, 0), n(i + 1, 1, 0), n(i, 1, 0),
                       n(i, 0, 1), n(i + 1, 0, 1), n(i + 1, 1, 1), n(i, 1, 1)] for i in range(2)])
    cells = {"hexahedron": hexes}
    if mixed:
        cells["quad"] = np.array([[n(i, 0, 1), n(i + 1, 0, 1), n(i + 1, 1, 1), n(i, 1, 1)] for i in range(2)])
        cells["triangle"] = np.array([[n(0, 0, 0), n(1, 0, 0), n(0, 1, 0)]])
    return X, cells


def _frame(k: int, n_node: int, n_cell: int):
    """Deterministic fields of frame k: displacement (n_node,3), temperature (n_node,), stress (n_cell,6),
    fibre (n_cell,3,3), and the time [s]."""
    rng = np.random.default_rng(k)
    point = {"displacement": rng.standard_normal((n_node, 3)), "temperature": rng.random(n_node)}
    cell = {"stress": rng.standard_normal((n_cell, 6)) * 1e3, "fibre": rng.standard_normal((n_cell, 3, 3)),
            "group": np.arange(n_cell, dtype=np.int64) + k}
    return 0.25 * k + 1e-9, point, cell


def _pvd_entries(path: Path) -> list[tuple[float, str]]:
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    return [(float(e.get("timestep")), e.get("file")) for e in root.iter("DataSet")]


# --------------------------------------------------------------------------------------------------------------------
# VTU + PVD


@pytest.mark.parametrize("mixed", [False, True], ids=["hex", "hex+quad+tri"])
def test_vtu_frames_round_trip_through_meshio(tmp_path, mixed):
    """Requirement: every VTU frame reads back with meshio bit-identical: reference points, cells, point fields,
    and the cell fields split over the blocks in the order given; the PVD lists the frames with their times."""
    X, cells = _mesh(mixed)
    n_cell = sum(len(c) for c in cells.values())
    with VtuSeries(tmp_path, "plate", X, cells) as series:
        for k in range(3):
            series.write(*_frame(k, len(X), n_cell))

    entries = _pvd_entries(tmp_path / "plate.pvd")
    assert [f for _, f in entries] == ["plate_00000.vtu", "plate_00001.vtu", "plate_00002.vtu"]
    assert [t for t, _ in entries] == [_frame(k, 1, 1)[0] for k in range(3)]  # exact: written with repr

    for k, (_, fname) in enumerate(entries):
        t, point, cell = _frame(k, len(X), n_cell)
        m = meshio.read(tmp_path / fname)
        np.testing.assert_array_equal(m.points, X)
        assert [(b.type, b.data.tolist()) for b in m.cells] == [(ct, c.tolist()) for ct, c in cells.items()]
        for name, a in point.items():
            np.testing.assert_array_equal(m.point_data[name], a)
        for name, a in cell.items():
            back = np.concatenate(m.cell_data[name])  # meshio gives one array per block
            np.testing.assert_array_equal(back, a.reshape(n_cell, -1).squeeze())
        assert m.cell_data["stress"][0].shape == (2, 6)  # one 6-component array, ParaView labels XX YY ZZ XY YZ XZ
        assert m.cell_data["fibre"][0].shape == (2, 9)  # (n,3,3) stored row-major as 9 components
        assert m.point_data["displacement"].dtype == np.float64


def test_vtu_points_override_writes_current_coordinates(tmp_path):
    """Requirement: ``write(points=x)`` puts x in that frame only; other frames keep the reference points."""
    X, cells = _mesh(False)
    x = X + 0.125
    s = VtuSeries(tmp_path, "p", X, cells)
    s.write(0.0, {"displacement": np.zeros_like(X)})
    s.write(1.0, {"displacement": x - X}, points=x)
    s.write(2.0)
    s.close()
    np.testing.assert_array_equal(meshio.read(tmp_path / "p_00000.vtu").points, X)
    np.testing.assert_array_equal(meshio.read(tmp_path / "p_00001.vtu").points, x)
    np.testing.assert_array_equal(meshio.read(tmp_path / "p_00002.vtu").points, X)


@pytest.mark.parametrize("cls", [VtuSeries, XdmfSeries])
def test_split_tensors_adds_named_scalar_components(tmp_path, cls):
    """Requirement: with split_tensors, a (n,6) field also appears as scalars <name>_XX ... in XX YY ZZ XY YZ XZ."""
    X, cells = _mesh(False)
    stress = np.arange(12, dtype=np.float64).reshape(2, 6) + 0.5
    s = cls(tmp_path, "s", X, cells, split_tensors=True)
    s.write(0.0, cell_data={"stress": stress})
    s.close()
    if cls is VtuSeries:
        cd = {k: np.concatenate(v) for k, v in meshio.read(tmp_path / "s_00000.vtu").cell_data.items()}
    else:
        with h5py.File(tmp_path / "s.h5", "r") as f:
            cd = {k: v[()] for k, v in f["frames/00000"].items()}
    np.testing.assert_array_equal(cd["stress"], stress if cls is VtuSeries else sym6_to_full9(stress))
    for j, comp in enumerate(TENSOR6_COMPONENTS):
        np.testing.assert_array_equal(cd[f"stress_{comp}"], stress[:, j])
    assert TENSOR6_COMPONENTS == ("XX", "YY", "ZZ", "XY", "YZ", "XZ")


def test_new_series_replaces_an_earlier_series_of_the_same_name(tmp_path):
    """Requirement: a rerun with fewer frames leaves no frame of the earlier run listed or lying beside it."""
    X, cells = _mesh(False)
    for n_frames in (4, 2):
        for s in open_series(["vtu", "xdmf"], tmp_path, "r", X, cells):
            for k in range(n_frames):
                s.write(float(k), {"displacement": np.full_like(X, n_frames)})
            s.close()
    assert sorted(p.name for p in tmp_path.glob("r_*.vtu")) == ["r_00000.vtu", "r_00001.vtu"]
    assert len(_pvd_entries(tmp_path / "r.pvd")) == 2
    with meshio.xdmf.TimeSeriesReader(tmp_path / "r.xdmf") as r:
        assert r.num_steps == 2
        r.read_points_cells()
        np.testing.assert_array_equal(r.read_data(1)[1]["displacement"], np.full_like(X, 2))


def test_empty_series_has_valid_empty_indexes(tmp_path):
    """Requirement: right after creation both indexes exist, parse, and list no frame."""
    X, cells = _mesh(False)
    open_series(["vtu", "xdmf"], tmp_path, "e", X, cells)
    assert _pvd_entries(tmp_path / "e.pvd") == []
    root = ET.parse(tmp_path / "e.xdmf").getroot()
    assert root.get("Version") == "3.0" and len(list(root.iter("Grid"))) == 1  # only the temporal collection


# --------------------------------------------------------------------------------------------------------------------
# XDMF + HDF5


@pytest.mark.parametrize("mixed", [False, True], ids=["hex", "hex+quad+tri"])
def test_xdmf_series_round_trip_through_meshio_time_series_reader(tmp_path, mixed, monkeypatch):
    """Requirement: meshio's XDMF TimeSeriesReader reads the mesh, every frame's time and fields bit-identical;
    the .h5 is written in out_dir, not in the working directory."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    out = tmp_path / "out"
    X, cells = _mesh(mixed)
    n_cell = sum(len(c) for c in cells.values())
    with XdmfSeries(out, "plate", X, cells) as series:
        for k in range(3):
            series.write(*_frame(k, len(X), n_cell))
    assert list(cwd.iterdir()) == []
    assert sorted(p.name for p in out.iterdir()) == ["plate.h5", "plate.xdmf"]

    with meshio.xdmf.TimeSeriesReader(out / "plate.xdmf") as reader:
        points, blocks = reader.read_points_cells()
        np.testing.assert_array_equal(points, X)
        assert [(b.type, b.data.tolist()) for b in blocks] == [(ct, c.tolist()) for ct, c in cells.items()]
        assert reader.num_steps == 3
        for k in range(3):
            t_ref, point, cell = _frame(k, len(X), n_cell)
            t, pd, cd = reader.read_data(k)
            assert t == t_ref
            for name, a in point.items():
                np.testing.assert_array_equal(pd[name], a)
            for name, a in cell.items():
                if name == "stress":  # XDMF holds symmetric tensors as the full 3x3 (see fdeck.io.frames)
                    a = sym6_to_full9(a)
                np.testing.assert_array_equal(np.concatenate(cd[name]), a.reshape(n_cell, -1).squeeze())


def test_sym6_to_full9_places_each_component():
    """Requirement: XX YY ZZ XY YZ XZ maps onto the symmetric 3x3, row-major."""
    full = sym6_to_full9(np.array([[11.0, 22.0, 33.0, 12.0, 23.0, 13.0]]))
    np.testing.assert_array_equal(full.reshape(3, 3), [[11, 12, 13], [12, 22, 23], [13, 23, 33]])


def test_xdmf_h5_layout_and_xml_attributes(tmp_path):
    """Requirement: the HDF5 holds /mesh/points, /mesh/topology once and /frames/<k:05d>/<field> per frame with a
    time attribute; the XML declares centres and attribute types (Scalar, Vector, Tensor: (n,6) becomes (n,9))."""
    X, cells = _mesh(True)
    n_cell = 5
    s = XdmfSeries(tmp_path, "m", X, cells)
    for k in range(2):
        s.write(*_frame(k, len(X), n_cell))
    x = X * 1.5
    s.write(7.0, {"displacement": x - X}, points=x)
    s.close()

    with h5py.File(tmp_path / "m.h5", "r") as f:
        np.testing.assert_array_equal(f["mesh/points"][()], X)
        topo = f["mesh/topology"][()]
        # Mixed: per cell [XDMF type id, nodes...]: hexahedron 9, quadrilateral 5, triangle 4.
        assert topo.tolist()[:9] == [9] + cells["hexahedron"][0].tolist()
        assert topo.size == 2 * 9 + 2 * 5 + 1 * 4
        assert sorted(f["frames"]) == ["00000", "00001", "00002"]
        for k in range(2):
            t, point, cell = _frame(k, len(X), n_cell)
            g = f[f"frames/{k:05d}"]
            assert g.attrs["time"] == t
            np.testing.assert_array_equal(g["stress"][()], sym6_to_full9(cell["stress"]))
            np.testing.assert_array_equal(g["displacement"][()], point["displacement"])
            np.testing.assert_array_equal(g["fibre"][()], cell["fibre"].reshape(n_cell, 9))
        np.testing.assert_array_equal(f["geometry/00002"][()], x)

    root = ET.parse(tmp_path / "m.xdmf").getroot()
    coll = root.find("Domain/Grid")
    assert coll.get("GridType") == "Collection" and coll.get("CollectionType") == "Temporal"
    grids = coll.findall("Grid")
    assert [float(g.find("Time").get("Value")) for g in grids] == [_frame(0, 1, 1)[0], _frame(1, 1, 1)[0], 7.0]
    attrs = {a.get("Name"): (a.get("Center"), a.get("AttributeType")) for a in grids[0].findall("Attribute")}
    assert attrs == {"displacement": ("Node", "Vector"), "temperature": ("Node", "Scalar"),
                     "stress": ("Cell", "Tensor"), "fibre": ("Cell", "Tensor"), "group": ("Cell", "Scalar")}
    assert grids[0].find("Topology").get("TopologyType") == "Mixed"
    assert grids[0].find("Topology").get("NumberOfElements") == "5"
    assert grids[2].find("Geometry/DataItem").text.strip() == "m.h5:/geometry/00002"
    with meshio.xdmf.TimeSeriesReader(tmp_path / "m.xdmf") as r:  # the override is also what meshio sees
        r.read_points_cells()
        np.testing.assert_array_equal(r.read_data(2)[1]["displacement"], x - X)


def test_paraview_readers_read_both_series(tmp_path):
    """Requirement: VTK's own readers (those ParaView uses) read the VTU frames and the XDMF series with the
    stress values in the right places (``vtk`` is in the test extra, not a runtime dependency)."""
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    X, cells = _mesh(True)
    stress = np.array([[11.0, 22, 33, 12, 23, 13]] * 5)
    for s in open_series(["vtu", "xdmf"], tmp_path, "v", X, cells):
        s.write(0.5, {"displacement": X * 0.1}, {"stress": stress})
    r = vtk.vtkXMLUnstructuredGridReader()
    r.SetFileName(str(tmp_path / "v_00000.vtu"))
    r.Update()
    np.testing.assert_array_equal(vtk_to_numpy(r.GetOutput().GetCellData().GetArray("stress")), stress)
    # The legacy XDMF reader (which reorders "Tensor6" and reads "Matrix" as one tuple) must see the full tensor.
    x = vtk.vtkXdmfReader()
    x.SetFileName(str(tmp_path / "v.xdmf"))
    x.Update()
    ug = x.GetOutputDataObject(0)
    np.testing.assert_array_equal(vtk_to_numpy(ug.GetCellData().GetArray("stress")), sym6_to_full9(stress))
    np.testing.assert_array_equal(vtk_to_numpy(ug.GetPoints().GetData()), X)
    assert [ug.GetCellType(i) for i in range(5)] == [12, 12, 9, 9, 5]  # VTK hexahedron, quad, triangle


# --------------------------------------------------------------------------------------------------------------------
# interface checks


def test_open_series_and_input_errors(tmp_path):
    """Requirement: bad input is an error naming the problem, never a silently wrong file."""
    X, cells = _mesh(False)
    vtu, xdmf = open_series(["vtu", "xdmf"], tmp_path, "a", X, cells)
    assert isinstance(vtu, VtuSeries) and isinstance(xdmf, XdmfSeries)
    with pytest.raises(ValueError, match="unknown frame formats"):
        open_series(["vtk"], tmp_path, "a", X, cells)
    with pytest.raises(ValueError, match="repeated"):
        open_series(["vtu", "vtu"], tmp_path, "a", X, cells)
    with pytest.raises(ValueError, match="unsupported cell type"):
        VtuSeries(tmp_path, "b", X, {"hex8": cells["hexahedron"]})
    with pytest.raises(ValueError, match=r"\(n_el, 4\)"):
        XdmfSeries(tmp_path, "b", X, {"quad": cells["hexahedron"]})
    with pytest.raises(ValueError, match="outside"):
        VtuSeries(tmp_path, "b", X, {"hexahedron": cells["hexahedron"] + 5})
    with pytest.raises(ValueError, match=r"\(n_node, 3\)"):
        VtuSeries(tmp_path, "b", X[:, :2], cells)
    with pytest.raises(ValueError, match="plain file name"):
        XdmfSeries(tmp_path, "a:b", X, cells)
    for s in (vtu, xdmf):
        s.write(1.0)
        with pytest.raises(ValueError, match="does not follow"):
            s.write(1.0)
        with pytest.raises(ValueError, match="first dimension 12"):
            s.write(2.0, {"displacement": np.zeros((5, 3))})
        with pytest.raises(ValueError, match="both points and cells"):
            s.write(2.0, {"u": np.zeros(12)}, {"u": np.zeros(2)})
        with pytest.raises(ValueError, match="'/'"):
            s.write(2.0, {"a/b": np.zeros(12)})
        s.write(2.0)  # failed calls wrote nothing and did not advance the series
        assert s.times == [1.0, 2.0]
        s.close()
        with pytest.raises(RuntimeError, match="closed"):
            s.write(3.0)


# --------------------------------------------------------------------------------------------------------------------
# history CSV


def test_history_round_trip_is_exact(tmp_path):
    """Requirement: read_history returns exactly the float64 values written (repr), including nan and inf."""
    rows = np.array([[0.0, 0.1 + 0.2, 1e-300], [1 / 3, -2.5e17, np.pi], [np.nan, np.inf, -np.inf]])
    with HistoryWriter(tmp_path / "h.csv", ["time", "kinetic_energy", "x"]) as h:
        for r in rows:
            h.write_row(r)
        with pytest.raises(ValueError, match="3 columns"):
            h.write_row([1.0, 2.0])
    text = (tmp_path / "h.csv").read_text()
    assert text.splitlines()[0] == "time,kinetic_energy,x"
    assert text.splitlines()[1] == "0.0,0.30000000000000004,1e-300"
    back = read_history(tmp_path / "h.csv")
    assert list(back) == ["time", "kinetic_energy", "x"]
    np.testing.assert_array_equal(np.column_stack(list(back.values())), rows)  # NaN == NaN in assert_array_equal


def test_history_rows_reach_the_file_before_close(tmp_path):
    """Requirement: each row is on disk as soon as write_row returns (a killed run keeps it)."""
    h = HistoryWriter(tmp_path / "h.csv", ["t", "e"])
    h.write_row([1.0, 2.0])
    assert (tmp_path / "h.csv").read_text() == "t,e\n1.0,2.0\n"
    h.close()


def test_read_history_tolerates_a_truncated_last_line(tmp_path):
    """Requirement: a last line cut by a kill (no newline) is dropped; complete lines are kept exactly."""
    p = tmp_path / "h.csv"
    p.write_text("t,e\n0.0,1.5\n0.001,2.25\n0.002,3.")
    back = read_history(p)
    np.testing.assert_array_equal(back["t"], [0.0, 0.001])
    np.testing.assert_array_equal(back["e"], [1.5, 2.25])
    p.write_text("t,e\n0.0,1.5\n0.0")  # cut inside the first field
    assert read_history(p)["t"].tolist() == [0.0]
    p.write_text("t,e\n")  # header only: columns with no rows
    assert {k: v.shape for k, v in read_history(p).items()} == {"t": (0,), "e": (0,)}
    p.write_text("t,e\n1.0\n2.0,3.0\n")  # a short line in the middle is damage, not truncation
    with pytest.raises(ValueError, match=":2: 1 fields"):
        read_history(p)


def test_history_rejects_bad_column_names(tmp_path):
    for cols in ([], ["a,b"], ["a", "a"], [""]):
        with pytest.raises(ValueError):
            HistoryWriter(tmp_path / "h.csv", cols)


# --------------------------------------------------------------------------------------------------------------------
# summary JSON


def test_write_json_atomic_converts_numpy_and_replaces_atomically(tmp_path):
    """Requirement: numpy scalars/arrays become JSON numbers/lists (non-finite -> null), indent 2; a failed write
    leaves the previous file intact and no temporary file."""
    p = tmp_path / "summary.json"
    obj = {"cycles": np.int64(12), "dt": np.float64(2.5e-7), "ok": np.bool_(True), "energy": np.array([1.0, 2.0]),
           "bad": np.float32(np.nan), "nested": ({"n": np.int32(3)},), "path": tmp_path / "x"}
    write_json_atomic(p, obj)
    text = p.read_text()
    assert text.startswith('{\n  "cycles": 12,') and text.endswith("}\n")
    assert json.loads(text) == {"cycles": 12, "dt": 2.5e-7, "ok": True, "energy": [1.0, 2.0], "bad": None,
                                "nested": [{"n": 3}], "path": str(tmp_path / "x")}
    with pytest.raises(TypeError, match="cannot write object"):
        write_json_atomic(p, {"x": object()})
    assert json.loads(p.read_text())["cycles"] == 12
    assert sorted(q.name for q in tmp_path.iterdir()) == ["summary.json"]
    atomic_write_text(p, "{}\n")
    assert p.read_text() == "{}\n"


# --------------------------------------------------------------------------------------------------------------------
# a run killed with SIGKILL

_CHILD = r"""
import sys, time
import numpy as np
from pathlib import Path
from fdeck.io.frames import open_series
from fdeck.io.history import HistoryWriter

out = Path(sys.argv[1])
n = 6
g = np.arange(n + 1, dtype=float)
X = np.stack(np.meshgrid(g, g, [0.0, 1.0], indexing="ij"), -1).reshape(-1, 3)
i = np.arange(len(X)).reshape(n + 1, n + 1, 2)
hexes = np.stack([i[:-1, :-1, 0], i[1:, :-1, 0], i[1:, 1:, 0], i[:-1, 1:, 0],
                  i[:-1, :-1, 1], i[1:, :-1, 1], i[1:, 1:, 1], i[:-1, 1:, 1]], -1).reshape(-1, 8)
series = open_series(["vtu", "xdmf"], out, "run", X, {"hexahedron": hexes})
hist = HistoryWriter(out / "history.csv", ["time", "frame", "energy"])
k = 0
while True:  # until killed
    for s in series:
        s.write(1e-3 * k, {"displacement": k * X}, {"stress": np.full((len(hexes), 6), float(k))})
    for j in range(20):
        hist.write_row([1e-3 * k + 5e-5 * j, k, np.sqrt(2.0) * (k + j)])
    k += 1
    time.sleep(0.01)
"""


def _listed(out: Path) -> tuple[int, int]:
    try:
        n_pvd = len(_pvd_entries(out / "run.pvd"))
        n_xdmf = len(ET.parse(out / "run.xdmf").getroot().find("Domain/Grid").findall("Grid"))
    except (FileNotFoundError, ET.ParseError, AttributeError):
        return 0, 0
    return n_pvd, n_xdmf


def test_sigkill_leaves_every_listed_frame_and_every_history_line_readable(tmp_path):
    """Requirement: a run killed with SIGKILL mid-loop leaves .pvd and .xdmf indexes whose every frame reads back
    with the values written, and a history CSV made only of complete lines."""
    script = tmp_path / "child.py"
    script.write_text(_CHILD)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    child = subprocess.Popen([sys.executable, str(script), str(out)], env=env, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30.0
        while min(_listed(out)) < 5:
            assert child.poll() is None, child.stderr.read().decode()
            assert time.monotonic() < deadline, "child wrote no frames in 30 s"
            time.sleep(0.005)
        time.sleep(0.013)  # land the kill anywhere in the loop, not right after an index update
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
        child.stderr.close()
    assert child.returncode == -signal.SIGKILL

    X_ref = None
    entries = _pvd_entries(out / "run.pvd")
    assert len(entries) >= 5
    for k, (t, fname) in enumerate(entries):
        m = meshio.read(out / fname)
        X_ref = m.points if X_ref is None else X_ref
        assert t == 1e-3 * k
        np.testing.assert_array_equal(m.point_data["displacement"], k * X_ref)
        np.testing.assert_array_equal(m.cell_data["stress"][0], np.full((36, 6), float(k)))

    with meshio.xdmf.TimeSeriesReader(out / "run.xdmf") as reader:
        points, _ = reader.read_points_cells()
        assert reader.num_steps >= 5
        for k in range(reader.num_steps):
            t, pd, cd = reader.read_data(k)
            assert t == 1e-3 * k
            np.testing.assert_array_equal(pd["displacement"], k * points)
            np.testing.assert_array_equal(cd["stress"][0], np.full((36, 9), float(k)))
    with h5py.File(out / "run.h5", "r") as f:
        for k in range(reader.num_steps):
            assert f[f"frames/{k:05d}"].attrs["time"] == 1e-3 * k
            np.testing.assert_array_equal(f[f"frames/{k:05d}/stress"][()], np.full((36, 9), float(k)))

    raw = (out / "history.csv").read_bytes()
    assert raw.endswith(b"\n")  # each row is one write() ending in its newline: no partial line on disk
    lines = raw.decode().splitlines()
    assert lines[0] == "time,frame,energy" and all(len(line.split(",")) == 3 for line in lines)
    hist = read_history(out / "history.csv")
    n = len(hist["frame"])
    assert n >= 20 * (len(entries) - 1)
    j = np.arange(n) % 20
    np.testing.assert_array_equal(hist["frame"], np.arange(n) // 20)
    np.testing.assert_array_equal(hist["energy"], np.sqrt(2.0) * (hist["frame"] + j))
