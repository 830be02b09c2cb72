"""The shape-based scene format (docs/formats.md): particles as disks, ellipses, spheres or ellipsoids with
poses, read into `model.shapes.scene_from_shapes`, and written back."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.errors import SceneError
from ..model.scene import LAW_DEFAULTS, LAW_KEYS
from ..model.shapes import SHAPE_FIELDS, SHAPES, rotation_matrix, scene_from_shapes
from ..model.tolerances import DEFAULT, Tolerances
from ..model.vec import rot_dim
from .entries import Reader, read_law
from .schema import read_header, read_particles

SHAPE_TOP_KEYS = {"dim", "title", "defaults", "particles"}
SHAPE_DEFAULT_KEYS = {*LAW_KEYS, "mobilised", "shear", "density"}


def is_shape_scene(data) -> bool:
    """A scene file in the shape format: no `contacts` array and at least one particle with a `shape`."""
    return (isinstance(data, dict) and "contacts" not in data and isinstance(data.get("particles"), list)
            and any(isinstance(item, dict) and "shape" in item for item in data["particles"]))


def _read_shape(rd: Reader, dim: int):
    """The `shape` table of a particle entry → a shape object (one-line SceneError on bad input)."""
    if not rd.has("shape"):
        rd.fail("shape", "missing (every particle of a shape scene needs one)")
    kinds = [kind for kind, cls in SHAPES.items() if cls.dim == dim]
    raw = rd.data["shape"]
    if not isinstance(raw, dict) or "kind" not in raw:
        rd.fail("shape", f"must be a table with kind = {' | '.join(kinds)}, got {raw!r}")
    kind = raw["kind"]
    if kind not in kinds:
        rd.fail("shape", f"kind: must be one of {', '.join(kinds)} in {dim}D, got {kind!r}")
    sub = Reader(rd.source, f"{rd.entry}: shape", raw, {"kind", *SHAPE_FIELDS[kind]})
    sizes = {key: float(sub.number(key)) for key in SHAPE_FIELDS[kind]}
    for key, value in sizes.items():
        if value <= 0:
            sub.fail(key, f"must be > 0, got {value:g}")
    return SHAPES[kind](**sizes)


def _read_orientation(rd: Reader, dim: int, tol: Tolerances):
    """2D `angle` (radians, default 0); 3D `rotation` (proper orthogonal 3x3, default identity)."""
    if dim == 2:
        return float(rd.number("angle", 0.0))
    if not rd.has("rotation"):
        return np.eye(3)
    R = rd.array("rotation", (3, 3))
    err = float(np.abs(R @ R.T - np.eye(3)).max())
    if err > tol.input_rtol or np.linalg.det(R) < 0:
        rd.fail("rotation", f"must be a proper rotation matrix (|RRᵀ - I| = {err:.3g}, det = {np.linalg.det(R):.6g})")
    return R


@dataclass(frozen=True, eq=False)
class ShapeFile:
    """A parsed shape-format scene: particles [(name, shape, (x, orientation))] and the contact law."""

    dim: int
    title: str
    particles: list
    law: dict
    mobilised: float
    shear: np.ndarray | None


def read_shape_file(data, source: str = "<scene>", tol: Tolerances = DEFAULT) -> ShapeFile:
    """Read the shape format (a parsed TOML/JSON dict) into its particles and contact law.

    Format: dim, title, [defaults] with k, alpha, mu, rolling_stiffness, mobilised (0..1, default 0) and
    shear (3D tangential-force direction, default [1, 0, 0]); [[particles]] with name, x, shape = {kind = "disk",
    radius = ..} | {kind = "ellipse", a, b} | {kind = "sphere", radius} | {kind = "ellipsoid", a, b, c}, and
    angle (2D, radians) or rotation (3D, 3x3). Errors are one-line SceneErrors naming file, entry and field.
    """
    top, dim, title = read_header(data, source, SHAPE_TOP_KEYS)
    drd = Reader(source, "defaults", data.get("defaults", {}), SHAPE_DEFAULT_KEYS)
    law = read_law(drd, dim, {**LAW_DEFAULTS, "rolling_stiffness": np.zeros((rot_dim(dim),) * 2)})
    density = float(drd.number("density", 1.0))
    if not density > 0:
        drd.fail("density", f"must be positive, got {density:g}")
    law["density"] = density
    mobilised = float(drd.number("mobilised", 0.0))
    if not 0.0 <= mobilised <= 1.0:
        drd.fail("mobilised", f"must be in [0, 1], got {mobilised:g}")
    shear = None
    if drd.has("shear"):
        if dim == 2:
            drd.fail("shear", "only for 3D scenes (2D tangential forces are along e3 × n)")
        shear = drd.array("shear", (3,))
        if not np.any(shear):
            drd.fail("shear", "must be a non-zero vector")

    allowed = {"name", "x", "shape", "angle" if dim == 2 else "rotation"}
    entries = read_particles(top, data, allowed, lambda rd, name: (
        name, _read_shape(rd, dim), (rd.array("x", (dim,)), _read_orientation(rd, dim, tol))))
    return ShapeFile(dim=dim, title=title, particles=entries, law=law, mobilised=mobilised, shear=shear)


def shape_scene_from_dict(data, source: str = "<scene>", tol: Tolerances = DEFAULT):
    """Read the shape format into a Scene via `scene_from_shapes` (see `read_shape_file` for the format)."""
    spec = read_shape_file(data, source, tol)
    dim, entries, law, mobilised, shear, title = (spec.dim, spec.particles, spec.law, spec.mobilised, spec.shear,
                                                  spec.title)
    try:
        return scene_from_shapes(dim, entries, k=law["k"], alpha=law["alpha"], mu=law["mu"], mobilised=mobilised,
                                 rolling_stiffness=law["rolling_stiffness"], shear=shear, title=title,
                                 source=source, tol=tol, density=law["density"])
    except (ValueError, RuntimeError) as exc:
        if isinstance(exc, SceneError):
            raise
        raise SceneError(" ".join(f"{source}: particles: {exc}".split())) from None


def shape_scene_to_dict(dim, particles, *, k=1.0, alpha=1.0, mu=0.5, mobilised=0.0, rolling_stiffness=0.0,
                        shear=None, title="") -> dict:
    """The shape format for the arguments of `scene_from_shapes`; `shape_scene_from_dict` reads it back to the
    same Scene (TOML/JSON-serialisable: floats and lists only)."""
    rolling = np.asarray(rolling_stiffness, float)
    defaults = {"k": float(k), "alpha": float(alpha), "mu": float(mu), "mobilised": float(mobilised),
                "rolling_stiffness": float(rolling) if rolling.ndim == 0 else rolling.tolist()}
    if shear is not None:
        defaults["shear"] = np.asarray(shear, float).tolist()
    items = []
    for name, shape, (x, orientation) in particles:
        item = {"name": name, "x": np.asarray(x, float).tolist(), "shape": shape.to_dict()}
        if dim == 2:
            item["angle"] = float(orientation if orientation is not None else 0.0)
        else:
            item["rotation"] = rotation_matrix(3, orientation).tolist()
        items.append(item)
    data = {"dim": dim, "title": title} if title else {"dim": dim}
    return {**data, "defaults": defaults, "particles": items}


