"""The contact-level scene format (docs/formats.md) as a schema: parsed TOML/JSON dicts and NPZ arrays →
`Scene`, column by column (vectorised), with one-line errors naming the entry and field; and back."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..model import grains
from ..model.errors import SceneError, describe, first
from ..model.periodic import check_cell, check_images
from ..model.scene import LAW_DEFAULTS, LAW_KEYS, STATES, Scene, build_scene
from ..model.tolerances import DEFAULT, Tolerances
from ..model.vec import rot_dim, tangent_basis
from .entries import ArrayTable, Reader, TextTable, read_law
from .syntax import paused_gc

TOP_KEYS = {"dim", "title", "cell", "defaults", "particles", "contacts"}
PARTICLE_KEYS = {"name", "x", "load", "moment", "mass", "inertia", "fixed"}
GRAIN_KEYS = {"shape", "orientation"}   # the grains' true shapes, for drawing (model/grains.py); NPZ: grains/…
CONTACT_KEYS = {"p", "q", "image", "point", "normal", "curvature_p", "curvature_q", "force", "moment", "state",
                "force_err", *LAW_KEYS}



def contact_scene_and_grains(data, source: str = "<scene>", tol: Tolerances = DEFAULT):
    """Build and validate a Scene from the parsed contact-level file format (a dict; scenes.py dispatches), with its
    grains' shapes (model.grains.from_particles) or None: (Scene, Grains | None)."""
    top, dim, title = read_header(data, source, TOP_KEYS)
    law = read_law(Reader(source, "defaults", data.get("defaults", {}), set(LAW_KEYS)), dim, _base_law(dim))
    if not isinstance(data.get("particles"), list) or not data["particles"]:
        top.fail("particles", "must be a non-empty array of tables")
    particles = TextTable(source, "particles", data["particles"], PARTICLE_KEYS | GRAIN_KEYS)
    contacts = TextTable(source, "contacts", data.get("contacts", []), CONTACT_KEYS)
    shaped = particles.present("shape").any() or particles.present("orientation").any()
    found = grains.from_particles(data["particles"], dim, source) if shaped else None
    return _scene_from_tables(dim, title, law, particles, contacts, source, tol, data.get("cell")), found


NPZ_META = ("dim", "title")
NPZ_CELL = "cell"   # (d, d) array, only in a periodic scene


def scene_arrays(scene: Scene, shapes=None) -> dict:
    """The file format as whole arrays (NPZ): `particles/<field>` and `contacts/<field>` over the entries, the
    same fields and units as the text format (2D curvatures and moments as scalars; p, q as 0-based particle
    indices, which scene_and_grains_from_arrays also accepts as names); `shapes` (model.grains.Grains, optional): the grains'
    `grains/…` arrays (Grains.arrays), only in a scene that has them."""
    names = np.array(scene.names, dtype=str)
    scalar = scene.dim == 2
    out = {"dim": np.array(scene.dim), "title": np.array(scene.title, dtype=str),
           "particles/name": names, "particles/x": scene.x, "particles/load": scene.load,
           "particles/moment": scene.load_moment[:, 0] if scalar else scene.load_moment,
           "contacts/p": scene.p, "contacts/q": scene.q, "contacts/point": scene.point,
           "contacts/normal": scene.normal, "contacts/force": scene.force,
           "contacts/moment": scene.moment[:, 0] if scalar else scene.moment,
           "contacts/k": scene.k, "contacts/alpha": scene.alpha, "contacts/mu": scene.mu,
           "contacts/rolling_stiffness": scene.rolling[:, 0, 0] if scalar else scene.rolling,
           "contacts/state": np.array(scene.state, dtype=str).reshape(scene.n_contacts)}
    if scene.cell is not None:
        out[NPZ_CELL] = scene.cell
        out["contacts/image"] = scene.image
    for key in ("curvature_p", "curvature_q"):
        K = getattr(scene, key)
        out[f"contacts/{key}"] = _kappa(K, scene.normal) if scalar else K
    if scene.fixed is not None:
        out["particles/fixed"] = scene.fixed
    if scene.force_err is not None:
        out["contacts/force_err"] = scene.force_err
    if scene.mass is not None:
        out["particles/mass"] = scene.mass
        out["particles/inertia"] = scene.inertia[:, 0, 0] if scalar else scene.inertia
    return out if shapes is None else {**out, **shapes.arrays()}


def _kappa(K: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """2D curvature tensors κ t⊗t back to κ = tᵀKt (M,)."""
    t = tangent_basis(normal)[:, :, 0]
    return np.einsum("mi,mij,mj->m", t, K, t)


def scene_and_grains_from_arrays(arrays: dict, source: str = "<scene>", tol: Tolerances = DEFAULT):
    """Build and validate a Scene from `scene_arrays`' dict (an .npz file), with the same checks as the text format,
    and its grains (model.grains.from_arrays) or None: (Scene, Grains | None)."""
    allowed = {*NPZ_META, NPZ_CELL, *(f"particles/{k}" for k in PARTICLE_KEYS),
               *(f"contacts/{k}" for k in CONTACT_KEYS)}
    unknown = sorted(k for k in set(arrays) - allowed if not k.startswith(grains.PREFIX))
    if unknown:
        raise SceneError(f"{source}: {unknown[0]}: unknown array (allowed: {', '.join(sorted(allowed))}, "
                          f"{grains.PREFIX}…)")
    meta = {}
    for key in NPZ_META:
        value = arrays.get(key)
        if value is not None and value.shape != ():
            raise SceneError(f"{source}: {key}: must be a single value, got shape {value.shape}")
        if value is not None:
            meta[key] = value.item()
    top, dim, title = read_header(meta, source, set(NPZ_META))

    def table(prefix: str) -> ArrayTable:
        cols = {key.split("/", 1)[1]: value for key, value in arrays.items() if key.startswith(prefix + "/")}
        lengths = {key: len(value) if value.ndim else -1 for key, value in cols.items()}
        n = lengths.get("name" if prefix == "particles" else "p", 0)
        wrong = next((key for key, m in lengths.items() if m != n), None)
        if wrong is not None:
            raise SceneError(f"{source}: {prefix}/{wrong}: has {lengths[wrong]} rows, expected {n}")
        return ArrayTable(source, prefix, cols, n)

    particles, contacts = table("particles"), table("contacts")
    if not len(particles):
        top.fail("particles", "must be a non-empty array")
    scene = _scene_from_tables(dim, title, _base_law(dim), particles, contacts, source, tol, arrays.get(NPZ_CELL))
    return scene, grains.from_arrays(arrays, dim, scene.names, source)


def _base_law(dim: int) -> dict:
    r = rot_dim(dim)
    return {**LAW_DEFAULTS, "rolling_stiffness": np.zeros((r, r))}


def _scene_from_tables(dim, title, law, particles, contacts, source, tol, cell=None) -> Scene:
    """The schema, column by column (vectorised): particles' names, positions and optional loads; contacts'
    particles, images, geometry, forces, law and state; the cell (periodic scenes). Errors name the first bad
    entry and its field."""
    r = rot_dim(dim)
    names = particles.strings("name")
    index = dict(zip(names, range(len(names))))
    if len(index) != len(names):
        seen = {}
        for i, name in enumerate(names):
            if name in seen:
                particles.label = lambda j: f"particles[{j}] ({names[j]!r})"
                particles.fail(i, "name", f"duplicate particle name (also particles[{seen[name]}])")
            seen[name] = i
    particles.label = lambda j: f"particles[{j}] ({names[j]!r})"
    x = particles.numbers("x", (dim,))
    moment_shape = () if dim == 2 else (3,)
    loads = (particles.numbers("load", (dim,), 0.0), particles.present("load"))
    moments = (particles.numbers("moment", moment_shape, 0.0).reshape(-1, r), particles.present("moment"))
    mass, inertia = _mass_columns(particles, dim, tol)
    fixed = _fixed_column(particles)

    M = len(contacts)
    p, q = _particle_column(contacts, "p", names, index), _particle_column(contacts, "q", names, index)
    contacts.label = lambda c: f"contacts[{c}] ({names[p[c]]}-{names[q[c]]})"
    image = contacts.numbers("image", (dim,), 0.0) if contacts.present("image").any() else None
    cell = check_cell(cell, dim, source, tol)
    image = None if image is None else check_images(image, M, dim, cell, source, contacts.label)
    itself = (p == q) if image is None else (p == q) & ~np.any(image != 0, axis=1)
    if np.any(itself):
        contacts.fail(first(itself), "q", "a particle cannot touch itself (p = q) but across the cell (an image)")
    point = contacts.numbers("point", (dim,))
    _check_unique_pairs(contacts, p, q, names, image, point)
    normal = contacts.numbers("normal", (dim,))
    norm = np.linalg.norm(normal, axis=1)
    bad = np.abs(norm - 1.0) > tol.input_rtol
    if bad.any():
        c = first(bad)
        contacts.fail(c, "normal", f"must be a unit vector, |n| = {norm[c]:.9g}")
    arrays = {"p": p, "q": q, "point": point, "normal": normal,
              **_curvature_columns(contacts, dim, normal, tol),
              "force": contacts.numbers("force", (dim,)),
              "moment": contacts.numbers("moment", moment_shape, 0.0).reshape(M, r)}
    for key, low, strict in (("k", 0.0, True), ("alpha", 0.0, False), ("mu", 0.0, False)):
        values = contacts.numbers(key, (), law[key])
        bad = values <= low if strict else values < low
        if bad.any():
            c = first(bad)
            contacts.fail(c, key, f"must be {'>' if strict else '>='} 0, got {values[c]}")
        arrays[key] = values
    arrays["rolling"] = _rolling_column(contacts, dim, law["rolling_stiffness"])
    state = contacts.strings("state", "auto")
    wrong = set(state) - set(STATES)
    if wrong:
        c = state.index(sorted(wrong)[0])
        contacts.fail(c, "state", f"must be one of {', '.join(STATES)}, got {state[c]!r}")
    arrays["state"] = tuple(state)
    scene = build_scene(dim, names, x, arrays, loads, moments, title=title, source=source, tol=tol,
                        entries=contacts.label, particle_entries=particles.label, mass=mass, inertia=inertia,
                        fixed=fixed, cell=cell, image=image)
    err = _force_err_column(contacts)
    return scene if err is None else replace(scene, force_err=err)


def _force_err_column(contacts) -> np.ndarray | None:
    """Optional `force_err` of each contact (issue 42): the radius of its force's stated uncertainty, force units,
    finite and >= 0, given for every contact or none (a cluster written by `extract` keeps its band). None: none."""
    have = contacts.present("force_err")
    if not have.any():
        return None
    if not have.all():
        contacts.fail(first(~have), "force_err", "missing (given for other contacts: give it for every one)")
    err = contacts.numbers("force_err")
    if (err < 0).any():
        contacts.fail(first(err < 0), "force_err", f"must be >= 0, got {err[first(err < 0)]}")
    return err


def _fixed_column(particles) -> np.ndarray | None:
    """Optional `fixed` (true/false) of each particle: a support with no dofs (absent: false). None if none is."""
    values, have = particles.raw("fixed")
    flags = np.zeros(len(particles), bool)
    if not have.any():
        return None
    given = np.asarray(values)
    if given.dtype != bool or given.shape != (int(have.sum()),):
        j = next((j for j, v in enumerate(values) if not isinstance(v, (bool, np.bool_))), 0)
        particles.fail(int(np.flatnonzero(have)[j]), "fixed", f"must be true or false, got {describe(values[j])}")
    flags[have] = given
    if flags.all():
        particles.fail(0, "fixed", "every particle is fixed: at least one must be free to move")
    return flags if flags.any() else None


def _particle_column(table, key: str, names: list, index: dict) -> np.ndarray:
    """Particle indices of a contact's p or q: names (text and NPZ) or, in NPZ, 0-based indices into the particles
    (what save_scene writes: no string work for 10⁶ contacts). An unknown particle names the contact."""
    given, _ = table.raw(key)
    if isinstance(given, np.ndarray) and given.dtype.kind in "iu":
        if given.shape != (len(table),):
            table.fail(None, key, f"must have shape ({len(table)},), got {given.shape}")
        bad = (given < 0) | (given >= len(names))
        if bad.any():
            table.fail(first(bad), key, f"particle index {given[first(bad)]} is not in 0..{len(names) - 1}")
        return given.astype(np.intp)
    labels = table.strings(key)
    found = list(map(index.get, labels))
    if None in found:
        c = found.index(None)
        table.label = lambda i: f"{table.name}[{i}]"
        table.fail(c, key, f"unknown particle {labels[c]!r}")
    return np.array(found, dtype=np.intp).reshape(len(labels))


def _check_unique_pairs(table, p: np.ndarray, q: np.ndarray, names: list, image=None, point=None) -> None:
    """One contact per unordered pair, image (q's image seen from p; p's image seen from q is its negative) and
    contact point (rigid bodies such as clumps touch at several points): the first repeat (in file order) is an
    error naming both entries."""
    if len(p) < 2:
        return
    swap = p > q
    rows = [np.minimum(p, q).astype(np.int64), np.maximum(p, q).astype(np.int64)]
    if image is not None:
        seen = np.where(swap[:, None], -image, image)
        lead = np.take_along_axis(seen, np.argmax(seen != 0, axis=1)[:, None], axis=1)
        seen = np.where((p == q)[:, None] & (lead < 0), -seen, seen)     # a self-contact: e and -e are one
        rows += list(seen.T)
    if point is not None:
        rows += list(point.T)
    order = np.lexsort(rows[::-1])
    key = np.stack(rows, axis=1)[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    if same.any():
        later = order[1:][same]
        c = int(later.min())
        j = int(order[:-1][same][np.argmin(later)])
        table.fail(c, "q", f"duplicate contact between {names[p[c]]!r} and {names[q[c]]!r} (also contacts[{j}])")


def _curvature_columns(table, dim: int, normal: np.ndarray, tol: Tolerances) -> dict:
    """curvature_p, curvature_q and their sum. 2D: scalars κ along t (convex < 0, κ = -1/ρ) → κ t⊗t, and the sum
    (κp + κq) t⊗t of the scalars themselves (docs/bounds.md: near a conforming contact the sum of the tensors would
    carry an error ε|κ| on a quantity of size |κp + κq|); 3D: the tensors (`_curvature_column`), summed later."""
    if dim == 3:
        return {key: _curvature_column(table, key, normal, tol) for key in ("curvature_p", "curvature_q")}
    t = tangent_basis(normal)[:, :, 0]
    tt = t[:, :, None] * t[:, None, :]
    kp, kq = table.numbers("curvature_p", ()), table.numbers("curvature_q", ())
    return {"curvature_p": kp[:, None, None] * tt, "curvature_q": kq[:, None, None] * tt,
            "curvature_sum": (kp + kq)[:, None, None] * tt}


def _curvature_column(table, key: str, normal: np.ndarray, tol: Tolerances) -> np.ndarray:
    """3D: a symmetric 3x3 tensor with K·n = 0 (input_rtol·|K|)."""
    K = table.numbers(key, (3, 3))
    scale = np.maximum(np.abs(K).max(axis=(1, 2), initial=0.0), 1e-300)
    asym = np.abs(K - np.swapaxes(K, 1, 2)).max(axis=(1, 2), initial=0.0)
    if np.any(asym > tol.input_rtol * scale):
        table.fail(first(asym > tol.input_rtol * scale), key, "curvature tensor must be symmetric")
    n = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    Kn = np.linalg.norm(np.einsum("mij,mj->mi", K, n), axis=1)
    if np.any(Kn > tol.input_rtol * scale):
        c = first(Kn > tol.input_rtol * scale)
        table.fail(c, key, f"curvature tensor must be tangent (K·n = 0), |K·n| = {Kn[c]:.3g}")
    return K


def _rolling_column(table, dim: int, default: np.ndarray) -> np.ndarray:
    """M^pq per contact: a scalar (× I; >= 0) in 2D, a scalar or a 3x3 matrix in 3D; the defaults elsewhere."""
    r = rot_dim(dim)
    key = "rolling_stiffness"
    matrix = table.matrix_form(key) if dim == 3 else np.zeros(len(table), bool)
    scalar = table.present(key) & ~matrix
    out = np.broadcast_to(default, (len(table), r, r)).copy()
    if scalar.any():
        value = table.numbers(key, (), 0.0, where=scalar)
        if np.any(value < 0):
            table.fail(first(value < 0), key, f"must be >= 0, got {value[first(value < 0)]}")
        out[scalar] = value[scalar, None, None] * np.eye(r)
    if matrix.any():
        out[matrix] = table.numbers(key, (3, 3), 0.0, where=matrix)[matrix]
    return out


def _mass_columns(table, dim: int, tol: Tolerances):
    """Optional `mass` (> 0) and `inertia` (2D: a number > 0; 3D: a symmetric positive definite 3x3 tensor in the
    global frame) of every particle, or of none: (mass (N,), inertia (N, r, r)) or (None, None)."""
    has_m, has_j = table.present("mass"), table.present("inertia")
    if not (has_m.any() or has_j.any()):
        return None, None
    both = has_m & has_j
    if not both.all():
        i = first(~both)
        table.fail(i, "mass" if not has_m[i] else "inertia",
                   "missing: the inertia metric needs mass and inertia for every particle (or for none)")
    mass = table.numbers("mass", ())
    if np.any(mass <= 0):
        table.fail(first(mass <= 0), "mass", f"must be positive, got {mass[first(mass <= 0)]:g}")
    if dim == 2:
        J = table.numbers("inertia", ())
        if np.any(J <= 0):
            table.fail(first(J <= 0), "inertia", f"must be positive, got {J[first(J <= 0)]:g}")
        return mass, J.reshape(-1, 1, 1)
    J = table.numbers("inertia", (3, 3))
    asym = np.abs(J - np.swapaxes(J, 1, 2)).max(axis=(1, 2))
    bad = asym > tol.input_rtol * np.abs(J).max(axis=(1, 2))
    if bad.any():
        table.fail(first(bad), "inertia", "must be a symmetric 3x3 tensor")
    J = 0.5 * (J + np.swapaxes(J, 1, 2))
    bad = np.linalg.eigvalsh(J).min(axis=1) <= 0
    if bad.any():
        table.fail(first(bad), "inertia", "must be positive definite")
    return mass, J


def read_header(data, source: str, allowed: set):
    """The top-level table: its reader, dim (the integer 2 or 3, required) and title (optional)."""
    top = Reader(source, "scene", data, allowed)
    if "dim" not in data:
        top.fail("dim", "missing (2 or 3)")
    dim = data["dim"]
    if type(dim) is not int or dim not in (2, 3):
        top.fail("dim", f"must be the integer 2 or 3, got {describe(dim)}")
    title = data.get("title", "")
    if not isinstance(title, str):
        top.fail("title", f"must be a string, got {describe(title)}")
    return top, int(dim), title


def read_particles(top: Reader, data: dict, allowed: set, read) -> list:
    """The `particles` array of a shape scene (small): one table each, with a unique name; `read(rd, name)`
    returns an entry's data."""
    particles = data.get("particles")
    if not isinstance(particles, list) or not particles:
        top.fail("particles", "must be a non-empty array of tables")
    out, index = [], {}
    for i, item in enumerate(particles):
        rd = Reader(top.source, f"particles[{i}]", item, allowed)
        name = rd.text("name")
        rd.entry = f"particles[{i}] ({name!r})"
        if name in index:
            rd.fail("name", f"duplicate particle name (also particles[{index[name]}])")
        index[name] = i
        out.append(read(rd, name))
    return out


def scene_to_dict(scene: Scene, shapes=None) -> dict:
    """The scene as the contact-level file format (docs/formats.md): a dict of plain lists and numbers.

    ``dim``, ``title``, ``particles`` (N dicts: ``name``, ``x`` (d,), ``load`` (d,), ``moment`` (a number in 2D,
    (3,) in 3D) and, where known, ``mass``, ``inertia``, ``fixed``) and ``contacts`` (M dicts: ``p``, ``q`` (names),
    ``point``, ``normal``, ``force`` (d,), ``curvature_p``, ``curvature_q`` (a number in 2D, (3, 3) in 3D),
    ``moment``, ``k``, ``alpha``, ``mu``, ``rolling_stiffness``, ``state``, and ``image`` (d,) in a periodic
    scene, which also has ``cell`` (d, d)); d = dim; with `shapes` (model.grains.Grains) each particle's ``shape``
    (and 3D ``orientation``). `scene_from_dict` reads it back to the same arrays. Built column-wise from
    `scene_arrays`.
    """
    cols = scene_arrays(scene)
    names = cols["particles/name"]
    cols["contacts/p"], cols["contacts/q"] = names[scene.p], names[scene.q]      # the text format names them

    def rows(prefix: str, keys: tuple) -> list:
        return [dict(zip(keys, values)) for values in zip(*(cols[f"{prefix}/{k}"].tolist() for k in keys))]

    contact_keys = ("p", "q") + (("image",) if scene.cell is not None else ()) + (
        "point", "normal", "curvature_p", "curvature_q", "force", "moment", "k", "alpha", "mu", "rolling_stiffness",
        "state") + (("force_err",) if scene.force_err is not None else ())
    particle_keys = (("name", "x", "load", "moment") + (("mass", "inertia") if scene.mass is not None else ())
                     + (("fixed",) if scene.fixed is not None else ()))
    with paused_gc():
        out = {"dim": scene.dim, "title": scene.title}
        if scene.cell is not None:
            out["cell"] = scene.cell.tolist()
        particles = rows("particles", particle_keys)
        for entry, extra in zip(particles, [] if shapes is None else shapes.entries()):
            entry.update(extra)                        # the grains' true shapes, for drawing (model/grains.py)
        return {**out, "particles": particles, "contacts": rows("contacts", contact_keys)}
