"""A small frictional packing made by YADE, exported as granstab's generic tables (Debian: apt-get install yade).

    yade -n -x examples/yade/make_packing.py [OUTDIR]          (a few seconds on one core)

200 spheres (radii 1 : 2 spread, friction angle 30°, Hookean kn from E = 5 MPa) in a box of six walls: compressed
isotropically to 10 kPa by the walls, then loaded triaxially (the y walls close at a constant strain rate while
x and z hold 10 kPa) so that contacts slide. A last step with the integrator off recomputes every contact at the
positions written, then examples/yade/export_granstab.py writes OUTDIR/particles.csv and OUTDIR/contacts.csv.
"""
import os
import sys

from yade import O, pack
from yade.utils import aabbWalls, sphere, unbalancedForce
from yade.wrapper import (Bo1_Box_Aabb, Bo1_Sphere_Aabb, ForceResetter, FrictMat, GlobalStiffnessTimeStepper,
                          Ig2_Box_Sphere_ScGeom, Ig2_Sphere_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator,
                          TriaxialStressController)
from math import radians

here = os.path.dirname(os.path.abspath(sys.argv[0]))     # yade runs the script with argv[0] = its path
out = sys.argv[1] if len(sys.argv) > 1 else here
os.makedirs(out, exist_ok=True)

O.materials.append(FrictMat(young=5e6, poisson=0.5, frictionAngle=radians(30), density=2600, label="spheres"))
O.materials.append(FrictMat(young=5e6, poisson=0.5, frictionAngle=0, density=0, label="walls"))
O.bodies.append(aabbWalls([(0, 0, 0), (1, 1, 1)], thickness=0, material="walls"))
cloud = pack.SpherePack()
cloud.makeCloud((0, 0, 0), (1, 1, 1), -1, 0.3333, 200, False, 0.95, seed=1)
O.bodies.append([sphere(c, r, material="spheres") for c, r in cloud])

triax = TriaxialStressController(thickness=0, stressMask=7, internalCompaction=False, goal1=-1e4, goal2=-1e4,
                                 goal3=-1e4, max_vel=1.0)
newton = NewtonIntegrator(damping=0.2)
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Box_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Box_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    GlobalStiffnessTimeStepper(active=1, timeStepUpdateInterval=100, timestepSafetyCoefficient=0.8),
    triax,
    newton,
]
while O.iter < 100000:                             # isotropic compression to 10 kPa
    O.run(1000, True)
    print("iso", O.iter, unbalancedForce(), triax.meanStress, triax.porosity, flush=True)
    if unbalancedForce() < 0.01 and abs(triax.meanStress + 1e4) < 1e2:
        break
triax.stressMask = 5                               # x, z: 10 kPa; y: strain rate
triax.goal2 = -0.05
start = triax.strain[1]
while abs(triax.strain[1] - start) < 0.01 and O.iter < 200000:
    O.run(200, True)
    print("dev", O.iter, triax.strain[1], unbalancedForce(), triax.meanStress, flush=True)
newton.dead = True                                 # one more step: forces at the positions written
O.run(1, True)
exec(open(os.path.join(here, "export_granstab.py")).read())
export_granstab(os.path.join(out, "particles.csv"), os.path.join(out, "contacts.csv"))
export_resultants(os.path.join(out, "yade_resultants.json"))   # YADE's own sums, to check the conversion
