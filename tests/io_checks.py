"""Checks every imported scene must pass (issue 9): unit normals from p to q, contact points on the centre line
at R − δ/2 from each centre, curvature −1/(R − δ/2) of the parallel surface, Newton's third law (one f^pq per
unordered pair), compression f·n < 0 or an elastic contact. `radius` is per scene particle; tolerances relative to the radii."""
import numpy as np

import granstab
from granstab.io import load


def check_contact_geometry(s, radius, rtol=1e-12):
    """Periodic scenes too: q's side is its copy x^q + image @ cell (the branch to it, r^qp from it)."""
    branch = s.branch
    d = np.linalg.norm(branch, axis=1)
    assert np.abs(np.linalg.norm(s.normal, axis=1) - 1).max() <= rtol
    assert np.min(np.sum(branch * s.normal, 1) / d) > 1 - 1e-8        # n^pq along p → q
    delta = radius[s.p] + radius[s.q] - d
    assert np.all(delta > 0)                                            # overlaps: R_p + R_q − d
    rho_p, rho_q = radius[s.p] - delta / 2, radius[s.q] - delta / 2
    a = np.linalg.norm(s.point - s.x[s.p], axis=1)
    b = np.linalg.norm(s.point - s.q_copy, axis=1)
    assert np.abs(a - rho_p).max() <= rtol * radius.max() * 10         # middle of the overlap, from p …
    assert np.abs(b - rho_q).max() <= rtol * radius.max() * 10         # … and from q: on the centre line
    assert np.all((a < d) & (b < d))                                    # between the centres
    eye = np.eye(s.dim)[None]
    tangent = eye - s.normal[:, :, None] * s.normal[:, None, :]
    trace = np.einsum("cij,cij->c", s.curvature_p, tangent) / (s.dim - 1)
    assert np.abs(trace * rho_p + 1).max() <= 1e-10                    # κ = −1/(R − δ/2)
    trace = np.einsum("cij,cij->c", s.curvature_q, tangent) / (s.dim - 1)
    assert np.abs(trace * rho_q + 1).max() <= 1e-10
    assert len({frozenset(pq) for pq in zip(s.p.tolist(), s.q.tolist())}) == s.n_contacts   # one image a pair here
    tension = np.sum(s.force * s.normal, 1) >= 0                        # f_n <= 0: kept, elastic, reported
    assert all(np.asarray(s.state)[tension] == "elastic")
    return delta, tension


def check_region_analyses(paths, region: str, min_particles: int):
    """A cluster cut from the middle of a 3D packing by `region` analyses on the dense path with identity errors at
    round-off (1e-10 relative) and at least its six rigid motions as zero eigenvalues of the loading branch."""
    s = load(paths, region=region).scene
    assert s.n_particles >= min_particles
    result = granstab.analyze(s, method="dense", max_sliding=8)
    assert max(result.errors.values()) <= 1e-10
    assert result.branches[0].n_zero >= 6


def with_atom_columns(src, dst, names, values_of_row):
    """A LAMMPS atom dump with columns `names` appended to every block, `values_of_row(row)` giving their values
    from the row's own columns ({name: float}, and "row": its index in the block): written here, independently of
    granstab's reader."""
    out, columns, row = [], None, 0
    for line in src.read_text().splitlines():
        if line.startswith("ITEM: ATOMS"):
            columns, row = line.split()[2:], 0
            out.append(" ".join([line, *names]))
        elif line.startswith("ITEM:"):
            columns = None
            out.append(line)
        elif columns is not None:
            values = values_of_row({"row": row, **dict(zip(columns, map(float, line.split())))})
            out.append(" ".join([line, *(f"{v:.17g}" for v in values)]))
            row += 1
        else:
            out.append(line)
    dst.write_text("\n".join(out) + "\n")
    return dst

