"""The screenshots of docs/export.md: a periodic jammed packing with one planted unstable spot, scanned, exported in
each format, every file read back with a reader that is not granstab's (vtk's XML reader, ASE, a plain parse of
the dump) and drawn headless with vtk (offscreen, EGL or OSMesa): particles coloured by the unstable fraction of
their clusters (white → dark red), contacts as lines (darker: larger normal force), the cell's outline, and in the
.vtp picture the first consistent mode's displacement as arrows.

    python3 examples/export/screenshots.py            # → docs/export/{vtp,xyz,dump}.png  (about 30 s)
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import ase.io
import numpy as np
import vtkmodules.vtkRenderingFreeType  # noqa: F401  (text)
import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (the render window's backend)
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkFiltersSources import vtkArrowSource, vtkSphereSource
from vtkmodules.vtkIOImage import vtkPNGWriter
from vtkmodules.vtkIOXML import vtkXMLPolyDataReader
from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor
from vtkmodules.vtkRenderingCore import (
    vtkActor,
    vtkColorTransferFunction,
    vtkGlyph3DMapper,
    vtkPolyDataMapper,
    vtkRenderer,
    vtkRenderWindow,
    vtkTextActor,
    vtkWindowToImageFilter,
)

import granstab
from granstab.export import export
from granstab.export.vtp import outline, polydata
from granstab.model import packings
from granstab.model.scene import CONTACT_FIELDS
from granstab.scan import scan

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "export"


def planted_packing():
    """64 jammed frictionless disks in a sheared periodic cell; particle 10's contacts sharpened (ρ = 0.4 r), so
    that its neighbourhood is unstable (eq:exampleH2) and the rest stays stable."""
    s = packings.jammed(2, 64, shear=0.05, seed=1)
    at = (s.p == 10) | (s.q == 10)
    factor = np.where(at, 2.5, 1.0)[:, None, None]
    arrays = {k: getattr(s, k) for k in CONTACT_FIELDS + ("state",) if k != "image"}
    arrays.update(curvature_p=s.curvature_p * factor, curvature_q=s.curvature_q * factor)
    return granstab.build_scene(2, s.names, s.x, arrays, cell=s.cell, image=s.image, title="planted jammed packing")


def read_vtp(path):
    reader = vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def from_vtp(folder: Path) -> dict:
    particles, contacts = read_vtp(folder / "packing.particles.vtp"), read_vtp(folder / "packing.contacts.vtp")
    pd, cd = particles.GetPointData(), contacts.GetCellData()
    return {"x": vtk_to_numpy(particles.GetPoints().GetData()), "radius": vtk_to_numpy(pd.GetArray("radius")),
            "fraction": vtk_to_numpy(pd.GetArray("unstable_fraction")),
            "ends": vtk_to_numpy(contacts.GetPoints().GetData()).reshape(-1, 2, 3),
            "fn": vtk_to_numpy(cd.GetArray("normal_force")),
            "cell": vtk_to_numpy(read_vtp(folder / "packing.cell.vtp").GetPoints().GetData()),
            "mode": vtk_to_numpy(pd.GetArray("mode1_displacement"))}


def from_xyz(folder: Path) -> dict:
    atoms = ase.io.read(folder / "packing.xyz", format="extxyz")
    rows = ase.io.read(folder / "packing.contacts.xyz", format="extxyz")
    start = atoms.positions[rows.arrays["p"]]
    return {"x": atoms.positions, "radius": atoms.arrays["radius"], "fraction": atoms.arrays["unstable_fraction"],
            "ends": np.stack([start, start + rows.arrays["branch"]], axis=1), "fn": rows.arrays["normal_force"],
            "cell": outline(np.asarray(atoms.cell)[:2, :2])}


def dump_table(path: Path) -> tuple[dict, np.ndarray]:
    """One block of a LAMMPS text dump by plain parsing: the columns by name and the box lines."""
    lines = path.read_text().splitlines()
    count, names = int(lines[3]), lines[8].split()[2:]
    rows = np.array([r.split() for r in lines[9:9 + count]], dtype=float)
    return dict(zip(names, rows.T)), np.array([ln.split() for ln in lines[5:8]], dtype=float)


def from_dump(folder: Path) -> dict:
    atoms, box = dump_table(folder / "packing.atoms.dump")
    local, _ = dump_table(folder / "packing.local.dump")
    x = np.c_[atoms["x"], atoms["y"], atoms["z"]]
    start = x[local["p"].astype(int) - 1]
    branch = np.c_[local["branch[1]"], local["branch[2]"], local["branch[3]"]]
    (_, hi_x, xy), (_, ly, _), _ = box                 # LAMMPS's bounds: xhi_bound = lx + xy (xy > 0)
    cell = np.array([[hi_x - xy, 0.0], [xy, ly]])
    return {"x": x, "radius": atoms["radius"], "fraction": atoms["unstable_fraction"],
            "ends": np.stack([start, start + branch], axis=1), "fn": local["normal_force"], "cell": outline(cell)}


def actors(data: dict) -> list:
    lut = vtkColorTransferFunction()
    lut.AddRGBPoint(0.0, 1.0, 1.0, 1.0)
    lut.AddRGBPoint(1.0, 0.5, 0.0, 0.0)
    disks = polydata(data["x"], np.arange(len(data["x"]))[:, None], lines=False)
    for name, values in (("radius", data["radius"]), ("fraction", data["fraction"])):
        array = numpy_to_vtk(np.ascontiguousarray(values, dtype=float), deep=True)
        array.SetName(name)
        disks.GetPointData().AddArray(array)
    sphere = vtkSphereSource()
    sphere.SetRadius(0.96)                                # a little gap: each disk on its own
    sphere.SetThetaResolution(40)
    glyphs = vtkGlyph3DMapper()
    glyphs.SetInputData(disks)
    sphere.Update()
    glyphs.SetSourceData(sphere.GetOutput())
    glyphs.SetScaleArray("radius")
    glyphs.SetScaleModeToScaleByMagnitude()
    glyphs.SetScalarModeToUsePointFieldData()
    glyphs.SelectColorArray("fraction")
    glyphs.SetLookupTable(lut)
    glyphs.SetScalarRange(0.0, 1.0)
    out = [vtkActor()]
    out[0].SetMapper(glyphs)
    m = len(data["ends"])
    lines = polydata(data["ends"].reshape(-1, 3) + [0, 0, 1.2], np.arange(2 * m).reshape(m, 2), lines=True)
    shade = numpy_to_vtk(np.ascontiguousarray(data["fn"] / data["fn"].max()), deep=True)
    shade.SetName("fn")
    lines.GetCellData().SetScalars(shade)
    grey = vtkColorTransferFunction()
    grey.AddRGBPoint(0.0, 0.65, 0.65, 0.7)
    grey.AddRGBPoint(1.0, 0.05, 0.05, 0.15)
    out += [line_actor(lines, grey, 3.0), line_actor(
        polydata(data["cell"] + [0, 0, 1.2], np.arange(len(data["cell"]))[None, :], lines=True), None, 2.5)]
    if "mode" in data:
        out.append(arrows(data["x"] + [0, 0, 1.5], data["mode"]))
    bar = vtkScalarBarActor()
    bar.SetLookupTable(lut)
    bar.SetTitle("unstable fraction")
    bar.SetNumberOfLabels(3)
    bar.SetPosition(0.87, 0.1)
    bar.SetWidth(0.1)
    bar.SetHeight(0.8)
    bar.UnconstrainedFontSizeOn()
    bar.GetTitleTextProperty().SetFontSize(16)
    bar.GetLabelTextProperty().SetFontSize(14)
    for prop in (bar.GetTitleTextProperty(), bar.GetLabelTextProperty()):
        prop.SetColor(0.05, 0.05, 0.1)
        prop.ShadowOff()
    return out + [bar]


def line_actor(lines, lut, width: float):
    mapper = vtkPolyDataMapper()
    mapper.SetInputData(lines)
    if lut is None:
        mapper.ScalarVisibilityOff()
    else:
        mapper.SetLookupTable(lut)
        mapper.SetScalarRange(0.0, 1.0)
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetLineWidth(width)
    if lut is None:
        actor.GetProperty().SetColor(0.1, 0.3, 0.8)
    return actor


def arrows(x: np.ndarray, u: np.ndarray):
    """The mode's displacement as arrows (scaled so that the largest is 1.5 mean radii long)."""
    points = polydata(x, np.arange(len(x))[:, None], lines=False)
    vec = numpy_to_vtk(np.ascontiguousarray(u * 1.5 / np.abs(u).max()), deep=True)
    vec.SetName("u")
    points.GetPointData().AddArray(vec)
    mapper = vtkGlyph3DMapper()
    mapper.SetInputData(points)
    arrow = vtkArrowSource()
    arrow.Update()
    mapper.SetSourceData(arrow.GetOutput())
    mapper.SetOrientationArray("u")
    mapper.SetScaleArray("u")
    mapper.SetScaleModeToScaleByMagnitude()
    mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(0.1, 0.5, 0.1)
    return actor


def render(data: dict, title: str, png: Path) -> None:
    renderer = vtkRenderer()
    renderer.SetBackground(0.78, 0.82, 0.88)
    for actor in actors(data):
        (renderer.AddViewProp if isinstance(actor, vtkScalarBarActor) else renderer.AddActor)(actor)
    text = vtkTextActor()
    text.SetInput(title)
    text.GetTextProperty().SetFontSize(18)
    text.GetTextProperty().SetColor(0.05, 0.05, 0.1)
    text.SetPosition(10, 10)
    renderer.AddViewProp(text)
    window = vtkRenderWindow()
    window.SetOffScreenRendering(1)
    window.SetSize(860, 700)
    window.AddRenderer(renderer)
    renderer.ResetCamera()
    camera = renderer.GetActiveCamera()
    bounds = renderer.ComputeVisiblePropBounds()
    shift = 0.09 * (bounds[1] - bounds[0])            # the packing left of the colour bar
    camera.SetFocalPoint(*np.add(camera.GetFocalPoint(), [shift, 0, 0]))
    camera.SetPosition(*np.add(camera.GetPosition(), [shift, 0, 0]))
    camera.Zoom(1.2)
    window.Render()
    grab = vtkWindowToImageFilter()
    grab.SetInput(window)
    grab.Update()
    writer = vtkPNGWriter()
    writer.SetFileName(str(png))
    writer.SetInputConnection(grab.GetOutputPort())
    writer.Write()


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    scene = planted_packing()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        scan(scene, tmp / "scan", workers=1, figures=False)
        for fmt, read, what in (("vtp", from_vtp, "read by vtk's XML reader, mode 1 as arrows"),
                                ("xyz", from_xyz, "read by ASE"), ("dump", from_dump, "plain parse of the pair")):
            export(scene, tmp / fmt, fmt=fmt, scan=tmp / "scan", modes=1 if fmt == "vtp" else 0)
            render(read(tmp / fmt), f"granstab export --out-format {fmt} ({what})", OUT / f"{fmt}.png")
            print(f"wrote {OUT / f'{fmt}.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
