"""Export a YADE simulation of clumps as granstab's clump tables (bodies.csv, members.csv, contacts.csv).

Run by examples/yade/make_clumps.py (tests/io/test_io_clumps.py, Debian's yade 2023.02a). After the step you want:

    exec(open("export_clumps.py").read())
    export_clumps("bodies.csv", "members.csv", "contacts.csv", gravity=newton.gravity)
    # then:  granstab convert bodies.csv members.csv contacts.csv --out scene.json

Conventions (docs/formats.md, "Clumps"): a clump (Body.isClump) is a row of bodies.csv: State.pos (the centre of
mass), State.mass, State.ori (w x y z: YADE's Quaternion prints and indexes (x, y, z, w), so the components are
named) and State.inertia (principal moments about the clump's own axes, rotated by ori). Its member spheres
(Body.clumpId) are rows of members.csv; a sphere outside any clump is a body of one member (itself); a clump
member that is not a sphere (Polyhedra, LevelSet, …) is refused (no curvature at a sharp vertex or edge). Every real interaction touching a member is a row of contacts.csv with
member ids: ScGeom's contactPoint (c), the force on id1 by id2 (YADE's F = normalForce + shearForce acts on id2,
so f = −F), and kn, ks, tan(friction angle). A wall (any non-sphere body) is id2 = −(its id + 1), with the member
first. The gravity of NewtonIntegrator is the `# gravity:` line. Export after a step with the integrator off
(NewtonIntegrator.dead = True), so that forces and positions belong to one state.
"""


def export_clumps(bodies_path="bodies.csv", members_path="members.csv", contacts_path="contacts.csv",
                  gravity=(0.0, 0.0, 0.0)):
    from yade import O
    from yade.wrapper import Sphere

    for b in O.bodies:
        if b is not None and b.isClumpMember and not isinstance(b.shape, Sphere):
            raise ValueError(f"export_clumps: body {b.id}: shape {type(b.shape).__name__} in clump {b.clumpId}: no "
                             "curvature at a sharp vertex or edge (clumps of spheres only)")
    alone = {b.id: b for b in O.bodies if b is not None and isinstance(b.shape, Sphere) and not b.isClumpMember}
    members = {b.id: b for b in O.bodies if b is not None and b.isClumpMember}
    members.update(alone)                       # a sphere outside any clump: a body of one member, itself
    clumps = {b.id: b for b in O.bodies if b is not None and b.isClump}
    clumps.update(alone)
    with open(bodies_path, "w") as out:
        out.write("# gravity: " + " ".join(repr(float(g)) for g in gravity) + "\n")
        if O.periodic:                                               # rows a_i = columns of hSize
            h = O.cell.hSize
            out.write("# cell: " + " ".join(repr(h[i, j]) for j in range(3) for i in range(3)) + "\n")
        out.write("body,x,y,z,mass,quatw,quati,quatj,quatk,inertia1,inertia2,inertia3\n")
        for i, b in clumps.items():
            s = b.state
            q = s.ori
            out.write(f"{i},{s.pos[0]!r},{s.pos[1]!r},{s.pos[2]!r},{s.mass!r},{q[3]!r},{q[0]!r},{q[1]!r},{q[2]!r},"
                      f"{s.inertia[0]!r},{s.inertia[1]!r},{s.inertia[2]!r}\n")
    with open(members_path, "w") as out:
        out.write("id,body,x,y,z,radius\n")
        for i, b in members.items():
            x, y, z = b.state.pos
            out.write(f"{i},{i if i in alone else b.clumpId},{x!r},{y!r},{z!r},{b.shape.radius!r}\n")
    with open(contacts_path, "w") as out:
        out.write("id1,id2,fx,fy,fz,cx,cy,cz,kn,kt,mu\n")
        for i in O.interactions:
            if not i.isReal:
                continue
            a, b = i.id1, i.id2
            if a not in members and b not in members:
                continue
            force = i.phys.normalForce + i.phys.shearForce          # on id2; −force on id1
            if a not in members:
                a, b, force = b, a, -force
            f1 = -force
            other = b if b in members else -(b + 1)
            c = i.geom.contactPoint
            mu = getattr(i.phys, "tangensOfFrictionAngle", 0.0)
            out.write(f"{a},{other},{f1[0]!r},{f1[1]!r},{f1[2]!r},{c[0]!r},{c[1]!r},{c[2]!r},"
                      f"{i.phys.kn!r},{i.phys.ks!r},{mu!r}\n")
