"""Named columns of per-contact tables (LAMMPS local dumps, generic tables): the names, the --columns mapping,
forces from whichever columns a file has, ids → particle indices and the particles' orientations, with one-line
errors."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.errors import SceneError
from ..model.vec import cross

CONTACT_NAMES = {
    "id1", "id2",                 # the two particles (ids as in the particle file; a negative id2 is a wall)
    "fx", "fy", "fz",             # total force on id1 by id2
    "fnx", "fny", "fnz",          # … or its normal part
    "ftx", "fty", "ftz",          # … plus its tangential part
    "fn", "ft",                   # 2D magnitudes: f = −f_n n + f_t t, t = e3 × n (RigidLibrary's convention)
    "nx", "ny", "nz",             # unit normal from id1 to id2 (default: the centre line)
    "mx", "my", "mz", "m",        # contact moment on id1 (3D components, 2D scalar)
    "frx", "fry", "frz",          # … or LAMMPS granular rolling resistance force f_r (pair/local p5 p6 p7):
                                  #   moment R_eff f_r × n on id1, R_eff = R1 R2/(R1 + R2)
    "mobilised",                  # nonzero: at the Coulomb limit by the file's own test
    "f_err", "fn_err", "ft_err",  # the force's stated uncertainty: |δf| <= f_err, or √(fn_err² + ft_err²) (issue 42)
    "kn", "kt", "mu",             # the file's contact law per contact: k = kn, α = kt/kn, μ
    "delx", "dely", "delz", "cx", "cy", "cz", "delta", "frame",   # read and checked or ignored
    "-",                          # ignore this column
}


def columns_option(text: str, width: int, where: str, found: str) -> list:
    """`--columns a,b,c`: one known name a column, as many as the file has."""
    names = [c.strip() for c in text.split(",")]
    bad = [c for c in names if c not in CONTACT_NAMES]
    if bad:
        raise SceneError(f"--columns: unknown name {bad[0]!r} (known: {', '.join(sorted(CONTACT_NAMES))})")
    if len(names) != width:
        raise SceneError(f"--columns: {len(names)} names for the {width} columns of {where} ({found})")
    return names


def column_note(path, header: list, names: list, given: bool, script: bool = False) -> dict:
    """The report's entry for a contact table's columns: which file, where their meaning came from (--columns, the
    LAMMPS input script's computes, or the header's own names) and each header name → its meaning ('-': ignored)."""
    how = "--columns" if given else ("the input script" if script and any(h not in CONTACT_NAMES for h in header)
                                     else "the header")
    return {"file": Path(path).name, "from": how, "map": [[h, n] for h, n in zip(header, names)]}


def contact_forces(where: str, col: dict, dim: int, normal=None):
    """f^pq on id1 from the columns there are: f*, or fn* + ft*, or (2D) scalars fn, ft along `normal`."""
    axes = "xyz"[:dim]

    def vector(prefix):
        present = [prefix + a in col for a in axes]
        if all(present):
            return np.stack([col[prefix + a] for a in axes], axis=1)
        if any(present):
            missing = next(prefix + a for a, ok in zip(axes, present) if not ok)
            raise SceneError(f"{where}: {missing}: no column ({dim}D needs {', '.join(prefix + a for a in axes)})")
        return None

    total, normal_part, tangential = vector("f"), vector("fn"), vector("ft")
    if total is not None:
        return total, "f (total force on id1)"
    if normal_part is not None:
        if tangential is None:
            return normal_part, "normal part only (no tangential columns: frictionless data?)"
        return normal_part + tangential, "normal part + tangential part"
    if "fn" in col and dim == 2 and normal is not None:
        t = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
        return -col["fn"][:, None] * normal + col.get("ft", np.zeros(len(normal)))[:, None] * t, \
            "f = −f_n n + f_t t, t = e3 × n"
    raise SceneError(f"{where}: fx: no force columns (fx fy [fz], fnx … + ftx …, or fn ft in 2D)")


def contact_moments(col: dict, dim: int, normal=None, r_eff=None):
    """m^pq on id1 (M, r) from mx my mz (2D: m), or from a rolling resistance force f_r: R_eff f_r × n (LAMMPS
    pair granular applies R_eff n_21 × f_r to atom 1, n_21 from atom 2 to atom 1); None without such columns."""
    if dim == 2 and "m" in col:
        return col["m"][:, None]
    if dim == 3 and all(f"m{a}" in col for a in "xyz"):
        return np.stack([col[f"m{a}"] for a in "xyz"], axis=1)
    if all(f"fr{a}" in col for a in "xyz"[:dim]) and normal is not None:
        return r_eff[:, None] * cross(np.stack([col[f"fr{a}"] for a in "xyz"[:dim]], axis=1), normal)
    return None


def to_indices(ids: np.ndarray, values: np.ndarray, name: str, line_of_row, what: str) -> np.ndarray:
    """Particle indices of the ids in `values`; an id not in `ids` is a one-line error naming its line.
    Integer ids in a compact range (DEM codes number particles 1..N) are looked up in a table, O(1) each;
    others by binary search."""
    table = _id_table(ids)
    if table is not None:
        lo, index = table
        key = values - lo
        inside = (key >= 0) & (key < len(index))
        found = np.full(len(values), -1, np.int64)
        found[inside] = index[key[inside].astype(np.int64)]
        bad = np.flatnonzero(~inside | (found < 0) | (ids[np.maximum(found, 0)] != values))
        if bad.size:
            raise SceneError(f"{line_of_row(bad[0])}: {name}: unknown particle id {values[bad[0]]:g} ({what})")
        return found
    order = np.argsort(ids)
    where = np.minimum(np.searchsorted(ids[order], values), len(ids) - 1)
    bad = np.flatnonzero(ids[order][where] != values)
    if bad.size:
        raise SceneError(f"{line_of_row(bad[0])}: {name}: unknown particle id {values[bad[0]]:g} ({what})")
    return order[where]


def _id_table(ids: np.ndarray):
    """(lowest id, index by id - lowest: -1 where no particle) for integer-valued ids whose range is at most a few
    times their number; None otherwise."""
    if len(ids) == 0 or ids.dtype.kind not in "iuf":
        return None
    lo, hi = ids.min(), ids.max()
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi - lo > 4 * len(ids) + 1024:
        return None
    if ids.dtype.kind == "f" and not np.array_equal(ids, np.floor(ids)):
        return None
    index = np.full(int(hi - lo) + 1, -1, np.int64)
    index[(ids - lo).astype(np.int64)] = np.arange(len(ids))
    return lo, index


def unique_ids(ids: np.ndarray, line_of_row, what: str) -> None:
    order = np.argsort(ids, kind="stable")
    same = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if same.size:
        row = order[same[0] + 1]
        raise SceneError(f"{line_of_row(row)}: id: {ids[row]} listed twice {what}")


#: per-particle orientation columns a reader takes: LAMMPS's quaternion (dump custom quatw quati quatj quatk) or,
#: in 2D, the angle about e3 (radians)
ORIENTATION_NAMES = ("quatw", "quati", "quatj", "quatk", "angle")
QUAT_TOL = 1e-6     # |q| - 1 allowed: files write quaternions to ~7+ digits; more than that is not a rotation


def particle_orientation(col: dict, dim: int, line_of_row, where: str) -> np.ndarray | None:
    """The particles' orientations as unit quaternions (N, 4), (w, x, y, z), from a table's columns (None when it
    has none): all four quat columns, or `angle` in 2D (q = (cos θ/2, 0, 0, sin θ/2)). A quaternion that is not of
    unit norm within QUAT_TOL, or a 2D one not about e3, is a one-line error naming the row: never renormalised."""
    quat = [n for n in ORIENTATION_NAMES[:4] if n in col]
    if not quat and "angle" not in col:
        return None
    if quat and "angle" in col:
        raise SceneError(f"{where}: angle: give the quaternion columns or angle, not both")
    if "angle" in col:
        if dim != 2:
            raise SceneError(f"{where}: angle: only for 2D (3D orientations are quatw quati quatj quatk)")
        half = np.asarray(col["angle"], dtype=float) / 2
        zero = np.zeros_like(half)
        return np.stack([np.cos(half), zero, zero, np.sin(half)], axis=1)
    if len(quat) != 4:
        missing = next(n for n in ORIENTATION_NAMES[:4] if n not in col)
        raise SceneError(f"{where}: {missing}: missing column (an orientation needs quatw quati quatj quatk)")
    q = np.stack([np.asarray(col[n], dtype=float) for n in ORIENTATION_NAMES[:4]], axis=1)
    off = np.abs(np.linalg.norm(q, axis=1) - 1.0)
    bad = np.flatnonzero(~(off <= QUAT_TOL))
    if len(bad):
        raise SceneError(f"{line_of_row(bad[0])}: quatw quati quatj quatk: not a unit quaternion "
                         f"(|q| = {np.linalg.norm(q[bad[0]]):.9g})")
    if dim == 2:
        tilted = np.flatnonzero(np.abs(q[:, 1:3]).max(axis=1) > QUAT_TOL)
        if len(tilted):
            raise SceneError(f"{line_of_row(tilted[0])}: quati quatj: a 2D orientation turns about e3 "
                             f"(quati = quatj = 0), got {q[tilted[0], 1]:.6g} {q[tilted[0], 2]:.6g}")
    return q



def force_uncertainty(col: dict, where) -> tuple[np.ndarray | None, str | None]:
    """Per contact row the radius of the force's stated uncertainty (docs/uncertainty.md): `f_err`, or `fn_err` and
    `ft_err` together (the ball around their box: √(fn_err² + ft_err²)); (None, None) without them. A missing,
    negative or non-finite value: SceneError naming the file, line and field (`where(row)`: "<file>: line L")."""
    names = ["f_err"] if "f_err" in col else [n for n in ("fn_err", "ft_err") if n in col]
    if not names:
        return None, None
    if names == ["fn_err"] or names == ["ft_err"]:
        raise SceneError(f"{where(0)}: {'ft_err' if names == ['fn_err'] else 'fn_err'}: missing column "
                         f"({names[0]} needs its partner, or give f_err)")
    for name in names:
        bad = ~(np.isfinite(col[name]) & (col[name] >= 0))
        if bad.any():
            r = int(np.flatnonzero(bad)[0])
            raise SceneError(f"{where(r)}: {name}: the force uncertainty must be finite and >= 0, got "
                             f"{col[name][r]!r}")
    value = col["f_err"] if names == ["f_err"] else np.hypot(col["fn_err"], col["ft_err"])
    return value.astype(float), " and ".join(names) + (" columns" if len(names) > 1 else " column")
