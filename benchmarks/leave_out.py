"""What a scene does not need costs nothing: 2D against the same disks as 3D spheres, no sliding contact against
one, no contact moments or rolling stiffness against some; each pair timed interleaved."""
from __future__ import annotations

import numpy as np

from granstab.analysis import analyze
from granstab.mechanics.stiffness import contact_blocks
from granstab.model.packings import lattice, random_packing
from granstab.model.scene import build_scene
from granstab.solve import sparse

from .assembly import assemble_vectorised
from .formatting import fmt_t, table
from .timing import timeit_pair

QUICK = {"particles": 1000, "repeat": 5, "min_time": 0.2}
FULL = {"particles": 3000, "repeat": 7, "min_time": 1.0}


def embed_3d(scene2):
    """The same planar configuration as a 3D scene (spheres in the z = 0 plane, same contacts)."""
    M = scene2.n_contacts
    z = lambda a: np.concatenate([a, np.zeros((len(a), 1))], axis=1)  # noqa: E731
    n3 = z(scene2.normal)
    t1 = np.stack([-scene2.normal[:, 1], scene2.normal[:, 0], np.zeros(M)], axis=1)
    e3 = np.tile([0.0, 0.0, 1.0], (M, 1))

    def curv(K2):
        kap = np.einsum("mi,mij,mj->m", t1[:, :2], K2, t1[:, :2])
        return kap[:, None, None] * (t1[:, :, None] * t1[:, None, :] + e3[:, :, None] * e3[:, None, :])
    arrays = {"p": scene2.p, "q": scene2.q, "point": z(scene2.point), "normal": n3,
              "curvature_p": curv(scene2.curvature_p), "curvature_q": curv(scene2.curvature_q),
              "force": z(scene2.force), "moment": np.zeros((M, 3)), "k": scene2.k, "alpha": scene2.alpha,
              "mu": scene2.mu, "rolling": scene2.rolling[:, :1, :1] * np.eye(3), "state": scene2.state}
    return build_scene(3, scene2.names, z(scene2.x), arrays)


def run(quick: bool = False) -> dict:
    cfg = QUICK if quick else FULL

    def pair(fa, fb, values=False):
        return timeit_pair(fa, fb, repeat=cfg["repeat"], min_time=cfg["min_time"], values=values)

    s2 = random_packing(2, cfg["particles"], seed=4)
    s3 = embed_3d(s2)
    t2, t3 = pair(lambda: assemble_vectorised(s2), lambda: assemble_vectorised(s3))
    p2, p3 = pair(lambda: sparse.sparse_problem(s2), lambda: sparse.sparse_problem(s3))
    a = random_packing(2, 40, mobilised=0.5, seed=5)
    b = random_packing(2, 40, mobilised=0.5, n_sliding=1, seed=5)
    (ta, ra), (tb, rb) = pair(lambda: analyze(a), lambda: analyze(b), values=True)
    base = lattice(3, 6, seed=6)
    mom = lattice(3, 6, moments=0.3, seed=6)
    roll = lattice(3, 6, rolling=0.05, seed=6)
    tb0, tm = pair(lambda: contact_blocks(base), lambda: contact_blocks(mom))
    tb1, tr = pair(lambda: contact_blocks(base), lambda: contact_blocks(roll))
    return {"particles": s2.n_particles, "contacts_3d": base.n_contacts,
            "2d_vs_3d": {"assembly": (t2, t3), "sparse_problem": (p2, p3)},
            "sliding": {"none": ta, "one": tb, "branches": (len(ra.branches), len(rb.branches))},
            "moments": {"none": tb0, "moments": tm, "none_2": tb1, "rolling": tr}}


def markdown(results: dict) -> str:
    (t2, t3), (p2, p3) = results["2d_vs_3d"]["assembly"], results["2d_vs_3d"]["sparse_problem"]
    s, m = results["sliding"], results["moments"]
    rows = [
        [f"2D scene vs the same disks as 3D spheres in a plane ({results['particles']:,} particles): contact blocks "
         "+ CSR", fmt_t(t2), fmt_t(t3), f"{t3 / t2:.1f}×"],
        ["… and the sparse set-up (assembly, scaling, rigid bases)", fmt_t(p2), fmt_t(p3), f"{p3 / p2:.1f}×"],
        ["no contact at yield (1 branch) vs one at yield (2 branches, consistency tests): analyze, 40 disks",
         fmt_t(s["none"]), fmt_t(s["one"]), f"{s['one'] / s['none']:.1f}×"],
        [f"3D contact blocks without vs with contact moments ({results['contacts_3d']:,} contacts)",
         fmt_t(m["none"]), fmt_t(m["moments"]), f"{m['moments'] / m['none']:.2f}×"],
        ["3D contact blocks without vs with rolling stiffness", fmt_t(m["none_2"]), fmt_t(m["rolling"]),
         f"{m['rolling'] / m['none_2']:.2f}×"],
    ]
    return "\n".join([
        "## Leave out what a scene does not need",
        "",
        "Each pair of scenes differs only in what is left out; the ratio is the saving of leaving it out. In 2D the "
        "rotation is a scalar (dofs 3 per particle, 6×6 blocks, no twirl or moment-rotation terms); without "
        "potentially sliding contacts there is one branch and no Appendix-D search; without contact moments or "
        "rolling stiffness their blocks are not built (stiffness.contact_blocks checks `has_moments`/"
        "`has_rolling`). Each pair is timed interleaved (A, B, A, B, …; medians) so that drifting load on the "
        "shared machine hits both alike. The planar 3D scene is only used for assembly: as a 3D problem it is a "
        "different mechanism (out-of-plane floppy modes), so its eigenproblem is not comparable.",
        "",
        table(["comparison", "without", "with", "cost of having it"], rows),
    ])
