"""Export a YADE simulation's current state as granstab's generic tables (particles.csv, contacts.csv).

Run by examples/yade/make_packing.py (tests/io/test_io_yade.py, Debian's yade 2023.02a). In a YADE script or shell,
after the simulation step you want:

    exec(open("export_granstab.py").read())
    export_granstab("particles.csv", "contacts.csv")
    # then:  granstab convert particles.csv contacts.csv --out scene.json

Conventions (YADE, ScGeom + FrictPhys, e.g. Law2_ScGeom_FrictPhys_CundallStrack): i.geom.normal points from
id1 to id2, the force F = i.phys.normalForce + i.phys.shearForce acts on id2 and −F on id1, so granstab's f^pq
(the force on id1 by id2) is −F; the normal is written too (nx ny nz, id1 → id2), so granstab checks it against
the centre line. Spheres become particles; an interaction of a sphere with any other body (wall, facet, box)
becomes a wall row (id2 = −(body id + 1)), i.e. an external load on the sphere. kn, ks and tan(friction angle) of
each interaction go into the kn, kt, mu columns, so granstab uses YADE's law. A periodic scene (O.periodic) writes
its cell as a `# cell:` line above the particle table's header: the rows are the cell vectors, the columns of
O.cell.hSize; granstab finds each contact's image of id2 as the minimum image (YADE's i.cellDist) and keeps the
seam contacts as periodic contacts. For forces consistent with the positions written, export after a step
whose integrator was off (NewtonIntegrator.dead = True), as make_packing.py does: otherwise the positions have
moved by one step since the forces were computed.
"""


def export_granstab(particles_path="particles.csv", contacts_path="contacts.csv"):
    from yade import O
    from yade.wrapper import Sphere

    spheres = {b.id: b for b in O.bodies if b is not None and isinstance(b.shape, Sphere)}
    with open(particles_path, "w") as out:
        if O.periodic:                                               # rows a_i = columns of hSize
            h = O.cell.hSize
            out.write("# cell: " + " ".join(repr(h[i, j]) for j in range(3) for i in range(3)) + "\n")
        out.write("id,x,y,z,radius\n")
        for i, b in spheres.items():
            x, y, z = b.state.pos
            out.write(f"{i},{x!r},{y!r},{z!r},{b.shape.radius!r}\n")
    with open(contacts_path, "w") as out:
        out.write("id1,id2,fx,fy,fz,nx,ny,nz,kn,kt,mu\n")
        for i in O.interactions:
            if not i.isReal:
                continue
            a, b = i.id1, i.id2
            if a not in spheres and b not in spheres:
                continue
            force = i.phys.normalForce + i.phys.shearForce          # on id2; −force on id1
            normal = i.geom.normal                                   # id1 → id2
            if a not in spheres:                                     # keep the sphere first
                a, b, force, normal = b, a, -force, -normal
            f1 = -force                                              # on id1 (a sphere) by id2
            other = b if b in spheres else -(b + 1)                  # a negative id2 is a wall
            mu = getattr(i.phys, "tangensOfFrictionAngle", 0.0)
            out.write(f"{a},{other},{f1[0]!r},{f1[1]!r},{f1[2]!r},{normal[0]!r},{normal[1]!r},{normal[2]!r},"
                      f"{i.phys.kn!r},{i.phys.ks!r},{mu!r}\n")


def export_resultants(path="yade_resultants.json", **extra):
    """YADE's own per-sphere force and torque sums (O.forces) and the iteration, plus `extra`, as JSON: what the
    tests check the conversion against."""
    import json

    from yade import O
    from yade.wrapper import Sphere

    ids = [b.id for b in O.bodies if b is not None and isinstance(b.shape, Sphere)]
    with open(path, "w") as fh:
        json.dump({"id": ids, "force": [list(O.forces.f(i)) for i in ids], "torque": [list(O.forces.t(i)) for i in ids],
                   "iter": O.iter, **extra}, fh)
