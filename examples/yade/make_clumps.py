"""A packing of clumps settled under gravity, made by YADE and exported as granstab's clump tables (Debian:
apt-get install yade).

    yade -n -x examples/yade/make_clumps.py [OUTDIR]          (about 10 s on one core)

60 rigid clumps (dimers and bent trimers of spheres of radius 0.04 and 0.05, random orientations, friction angle
30°, Hookean kn from E = 1 MPa) dropped into a box of five walls under gravity g = 9.81 along −z and left to
settle (damping 0.4) until the unbalanced force is below 0.5 %. A last step with the integrator off recomputes
every contact at the positions written, then examples/yade/export_clumps.py writes OUTDIR/bodies.csv,
OUTDIR/members.csv and OUTDIR/contacts.csv.
"""
import os
import random
import sys
from math import radians

from yade import O, Quaternion, Vector3
from yade.utils import aabbWalls, sphere, unbalancedForce
from yade.wrapper import (Bo1_Box_Aabb, Bo1_Sphere_Aabb, ForceResetter, FrictMat, GlobalStiffnessTimeStepper,
                          Ig2_Box_Sphere_ScGeom, Ig2_Sphere_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator)

here = os.path.dirname(os.path.abspath(sys.argv[0]))
out = sys.argv[1] if len(sys.argv) > 1 else here
os.makedirs(out, exist_ok=True)
random.seed(3)

O.materials.append(FrictMat(young=1e6, poisson=0.5, frictionAngle=radians(30), density=2600, label="grains"))
O.materials.append(FrictMat(young=1e6, poisson=0.5, frictionAngle=0, density=0, label="walls"))
walls = aabbWalls([(0, 0, 0), (0.6, 0.6, 2.0)], thickness=0, material="walls")
O.bodies.append([w for w in walls if not (w.state.pos[2] > 1.9)])          # no lid
shapes = [[(-0.035, 0, 0, 0.05), (0.035, 0, 0, 0.04)],                        # dimer
          [(-0.05, -0.02, 0, 0.04), (0, 0.02, 0, 0.05), (0.05, -0.02, 0, 0.04)]]   # bent trimer
k = 0
for ix in range(4):
    for iy in range(4):
        for iz in range(4):
            if k == 60:
                break
            k += 1
            centre = Vector3(0.09 + 0.14 * ix, 0.09 + 0.14 * iy, 0.1 + 0.14 * iz)
            turn = Quaternion(Vector3(random.gauss(0, 1), random.gauss(0, 1), random.gauss(0, 1)).normalized(),
                              random.uniform(0, 6.283))
            spheres = [sphere(centre + turn * Vector3(a, b, c), r, material="grains")
                       for a, b, c, r in shapes[k % 2]]
            O.bodies.appendClumped(spheres)
newton = NewtonIntegrator(damping=0.4, gravity=(0, 0, -9.81))
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Box_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Box_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    GlobalStiffnessTimeStepper(active=1, timeStepUpdateInterval=100, timestepSafetyCoefficient=0.8),
    newton,
]
while O.iter < 200000:
    O.run(2000, True)
    print("settle", O.iter, O.time, unbalancedForce(), flush=True)
    if O.iter > 10000 and unbalancedForce() < 0.005:
        break
newton.dead = True                                 # one more step: forces at the positions written
O.run(1, True)
exec(open(os.path.join(here, "export_clumps.py")).read())
export_clumps(os.path.join(out, "bodies.csv"), os.path.join(out, "members.csv"), os.path.join(out, "contacts.csv"),
              gravity=newton.gravity)
