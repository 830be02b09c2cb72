"""VTK XML PolyData (.vtp) through the `vtk` package's own writer (ParaView's reader is the same library): per
frame NAME.particles.vtp (a vertex cell a particle, the particle fields as point data), NAME.contacts.vtp (a line
cell a contact from x^p to q's copy, the contact fields as cell data) and, for a periodic scene, NAME.cell.vtp (the
cell's outline as one closed polyline). Scalars of the frame (mode eigenvalues) are field data of the particles.
A sequence adds NAME.pvd, ParaView's collection of the frames' files, each file a part.
"""
from __future__ import annotations

import itertools
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..model.errors import require
from .fields import FrameFields, as3

PARTS = ("particles", "contacts", "cell")


def _vtk():
    require("vtkmodules", "export", "granstab export --format vtp")
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonCore import vtkPoints, vtkStringArray
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter
    return numpy_support, vtkPoints, vtkStringArray, vtkCellArray, vtkPolyData, vtkXMLPolyDataWriter


def vtk_array(name: str, values: np.ndarray):
    """A named VTK array (deep copy): strings as vtkStringArray, numbers in their own type, (n, 3) as 3 components."""
    numpy_support, _, vtkStringArray, *_ = _vtk()
    values = np.asarray(values)
    if values.dtype.kind in "US":
        out = vtkStringArray()
        out.SetNumberOfValues(len(values))
        for i, v in enumerate(values):
            out.SetValue(i, str(v))
    else:
        out = numpy_support.numpy_to_vtk(np.ascontiguousarray(values), deep=True)
    out.SetName(name)
    return out


def polydata(points: np.ndarray, cells: np.ndarray, lines: bool):
    """PolyData of `points` (n, 3) with one cell a row of `cells` (connectivity, equal lengths): vertices or lines."""
    numpy_support, vtkPoints, _, vtkCellArray, vtkPolyData, _ = _vtk()
    pts = vtkPoints()
    pts.SetData(numpy_support.numpy_to_vtk(np.ascontiguousarray(points, dtype=float), deep=True))
    cells = np.asarray(cells, dtype=np.int64)
    array = vtkCellArray()
    offsets = np.arange(0, cells.size + 1, max(cells.shape[1], 1), dtype=np.int64) if cells.size else np.zeros(1, np.int64)
    array.SetData(numpy_support.numpy_to_vtkIdTypeArray(offsets, deep=True),
                  numpy_support.numpy_to_vtkIdTypeArray(cells.ravel(), deep=True))
    data = vtkPolyData()
    data.SetPoints(pts)
    (data.SetLines if lines else data.SetVerts)(array)
    return data


def write_polydata(data, path: Path) -> Path:
    *_, writer_class = _vtk()
    writer = writer_class()
    writer.SetFileName(str(path))
    writer.SetInputData(data)
    writer.SetDataModeToBinary()
    if not writer.Write():
        raise OSError(f"cannot write {path}")
    return path


def outline(cell: np.ndarray) -> np.ndarray:
    """The cell's edges as one polyline of points (3D: the 12 edges, some walked twice), corner 0 at the origin."""
    a = as3(cell)
    if len(cell) == 2:
        corners = [0 * a[0], a[0], a[0] + a[1], a[1], 0 * a[0]]
    else:
        c = {bits: sum(b * v for b, v in zip(bits, a)) for bits in itertools.product((0, 1), repeat=3)}
        walk = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1),
                (0, 0, 1), (1, 0, 1), (1, 0, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1), (0, 1, 0)]
        corners = [c[w] for w in walk]
    return np.array(corners, dtype=float)


def write_frame(frame: FrameFields, out: Path, stem: str) -> list[Path]:
    """The frame's .vtp files (module docstring) in `out`, named STEM.PART.vtp."""
    n, m = len(frame.positions), len(frame.ends)
    particles = polydata(frame.positions, np.arange(n)[:, None], lines=False)
    for name, values in frame.particles.items():
        particles.GetPointData().AddArray(vtk_array(name, values))
    for name, value in frame.info.items():
        particles.GetFieldData().AddArray(vtk_array(name, np.array([value])))
    contacts = polydata(frame.ends.reshape(-1, 3), np.arange(2 * m).reshape(m, 2), lines=True)
    for name, values in frame.contacts.items():
        contacts.GetCellData().AddArray(vtk_array(name, values))
    written = [write_polydata(particles, out / f"{stem}.particles.vtp"),
               write_polydata(contacts, out / f"{stem}.contacts.vtp")]
    if frame.cell is not None:
        corners = outline(frame.cell)
        written.append(write_polydata(polydata(corners, np.arange(len(corners))[None, :], lines=True),
                                      out / f"{stem}.cell.vtp"))
    return written


def write_collection(entries: list[tuple[float, list[Path]]], path: Path) -> Path:
    """ParaView's .pvd collection: each frame's files at its time, one part a file kind (particles, contacts,
    cell). The vtk package writes data files, not collections; this is the format's whole schema."""
    root = ElementTree.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ElementTree.SubElement(root, "Collection")
    for time, files in entries:
        for f in files:
            part = PARTS.index(f.name.split(".")[-2])
            ElementTree.SubElement(collection, "DataSet", timestep=repr(float(time)), group="", part=str(part),
                                   file=f.name)
    ElementTree.ElementTree(root).write(path, xml_declaration=True, encoding="utf-8")
    return path
