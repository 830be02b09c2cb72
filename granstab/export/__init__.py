"""Files that open in OVITO and ParaView: a packing's particles, contacts and cell with the scan's verdicts and the
whole packing's consistent modes, as VTK PolyData, extended XYZ or a LAMMPS-style dump pair (docs/export.md).

    frame = granstab.export.frame_of(scene, scan="scan/", modes=2)    # the arrays, by name (fields.FrameFields)
    granstab.export.write([frame], "out/", fmt="vtp")                  # out/packing.particles.vtp, ... → paths
    granstab.export.export(scene, "out/", fmt="xyz", scan="scan/")     # both at once

A sequence is a list of frames (each with its `time`): vtp writes a file set a frame and a .pvd collection, xyz and
dump one file holding every frame (a trajectory for OVITO and ASE). `.vtp` needs the `export` extra (vtk).
"""
from __future__ import annotations

from pathlib import Path

from ..model.errors import SceneError
from ..model.scene import Scene
from . import dump, xyz
from .fields import STATE_CODES, VERDICT_CODES, FrameFields, add_scan, quaternion_xyzw, scene_frame, shape_fields
from .modes import add_modes

FORMATS = ("vtp", "xyz", "dump")

__all__ = ["FORMATS", "STATE_CODES", "VERDICT_CODES", "FrameFields", "export", "frame_of", "write"]


def frame_of(scene: Scene, *, scan=None, modes: int = 0, time: float = 0.0, extra: dict | None = None,
             orientation=None, analysis: dict | None = None, shape=None) -> FrameFields:
    """One frame's fields: the scene's own, the scan folder's verdicts (`scan`: a granstab scan output of this
    packing), the `modes` lowest consistent modes of the whole packing, `extra` per-particle arrays (N,) and the
    particles' `orientation` where the input gives it ((N, 4) unit quaternions w, x, y, z: `io.Loaded.orientation`),
    their superquadric `shape` ((N, 5) a, b, c, n1, n2: `io.Loaded.shape`; fields.shape_fields);
    `analysis`: the options of the modes' analysis (export.modes.modes_options)."""
    frame = scene_frame(scene, time)
    if orientation is not None:
        frame.particles["orientation"] = quaternion_xyzw(orientation, scene)
    if shape is not None:
        frame.particles.update(shape_fields(shape, orientation, scene))
    if scan is not None:
        add_scan(frame, scene, scan)
    add_modes(frame, scene, modes, analysis=analysis)
    for name, values in (extra or {}).items():
        if len(values) != scene.n_particles:
            raise SceneError(f"{scene.source}: {name}: {len(values)} values for {scene.n_particles} particles")
        frame.particles[name] = values
    return frame


def write(frames: list[FrameFields], out, fmt: str = "vtp", stem: str = "packing") -> list[Path]:
    """Write `frames` (one, or a sequence) to the folder `out` (created) as `fmt`; the paths written."""
    if fmt not in FORMATS:
        raise SceneError(f"--format: one of {', '.join(FORMATS)}, got {fmt!r}")
    if not frames:
        raise SceneError(f"{out}: no frame to export")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if fmt == "xyz":
        return xyz.write(frames, out, stem)
    if fmt == "dump":
        return dump.write(frames, out, stem)
    from . import vtp
    if len(frames) == 1:
        return vtp.write_frame(frames[0], out, stem)
    entries = [(f.time, vtp.write_frame(f, out, f"{stem}.{i:05d}")) for i, f in enumerate(frames)]
    return [p for _, files in entries for p in files] + [vtp.write_collection(entries, out / f"{stem}.pvd")]


def export(scene: Scene, out, *, fmt: str = "vtp", scan=None, modes: int = 0, stem: str = "packing") -> list[Path]:
    """`frame_of` then `write`: one packing to `out` as `fmt`."""
    if fmt not in FORMATS:       # before the analysis, not after it
        raise SceneError(f"--format: one of {', '.join(FORMATS)}, got {fmt!r}")
    return write([frame_of(scene, scan=scan, modes=modes)], out, fmt, stem)
