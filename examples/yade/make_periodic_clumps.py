"""A packing of clumps in a fully periodic cell made by YADE, exported as granstab's clump tables with the cell
(Debian: apt-get install yade).

    yade -n -x examples/yade/make_periodic_clumps.py [OUTDIR]          (about 10 s on one core)

27 rigid clumps (dimers and bent trimers of spheres of radius 0.04 and 0.05, random orientations, friction angle
30°, Hookean kn from E = 1 MPa) on a loose grid in a periodic cell (O.periodic = True), compressed isotropically by
the cell to 10 kPa (PeriTriaxController), without gravity, then held (the cell fixed) until YADE's unbalanced
force is below 1e-6 (or for 20000 more steps).
Clumps and contacts cross the cell's faces: YADE keeps positions unwrapped (a clump's members move with it), a
contact's second member may be an image (Interaction.cellDist). A last step with the integrator off recomputes
every contact at the positions written, then examples/yade/export_clumps.py writes OUTDIR/bodies.csv (with its
`# cell:` line), OUTDIR/members.csv and OUTDIR/contacts.csv. Runs are not bit-reproducible (Debian's yade
2023.02a: the contact count varies by a few from run to run); the tests check properties, not numbers.
"""
import os
import random
import sys
from math import radians

from yade import O, Matrix3, Quaternion, Vector3
from yade.utils import PWaveTimeStep, kineticEnergy, sphere, unbalancedForce
from yade.wrapper import (Bo1_Sphere_Aabb, ForceResetter, FrictMat,
                          Ig2_Sphere_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator,
                          PeriTriaxController)

here = os.path.dirname(os.path.abspath(sys.argv[0]))
out = sys.argv[1] if len(sys.argv) > 1 else here
os.makedirs(out, exist_ok=True)
random.seed(5)

O.periodic = True
side = 0.6
O.cell.hSize = Matrix3(side, 0, 0, 0, side, 0, 0, 0, side)
O.materials.append(FrictMat(young=1e6, poisson=0.5, frictionAngle=radians(30), density=2600, label="grains"))
shapes = [[(-0.035, 0, 0, 0.05), (0.035, 0, 0, 0.04)],                        # dimer
          [(-0.05, -0.02, 0, 0.04), (0, 0.02, 0, 0.05), (0.05, -0.02, 0, 0.04)]]   # bent trimer
k = 0
for ix in range(3):
    for iy in range(3):
        for iz in range(3):
            k += 1
            centre = Vector3(0.1 + 0.2 * ix, 0.1 + 0.2 * iy, 0.1 + 0.2 * iz)     # apart: no overlap
            turn = Quaternion(Vector3(random.gauss(0, 1), random.gauss(0, 1), random.gauss(0, 1)).normalized(),
                              random.uniform(0, 6.283))
            spheres = [sphere(centre + turn * Vector3(a, b, c), r, material="grains")
                       for a, b, c, r in shapes[k % 2]]
            O.bodies.appendClumped(spheres)
triax = PeriTriaxController(goal=(-1e4, -1e4, -1e4), stressMask=7, maxUnbalanced=0.005, relStressTol=1e-3,
                            maxStrainRate=(0.1, 0.1, 0.1), dynCell=True, mass=0.2)
newton = NewtonIntegrator(damping=0.4)
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    triax,
    newton,
]
O.dt = 0.2 * PWaveTimeStep()                       # fixed: with GlobalStiffnessTimeStepper some runs blew up here
while O.iter < 100000:                             # isotropic compression to about 10 kPa
    O.run(1000, True)
    print("compress", O.iter, O.cell.hSize[0, 0], unbalancedForce(), kineticEnergy(), triax.stress, flush=True)
    if unbalancedForce() < 0.1 and max(abs(s + 1e4) for s in triax.stress) < 1e3:
        break
triax.dead = True                                  # the cell held: the clumps come to rest
O.cell.velGrad = Matrix3(0, 0, 0, 0, 0, 0, 0, 0, 0)
rest = O.iter
while O.iter < rest + 20000:                       # (a rattler may keep drifting: the kinetic energy stays)
    O.run(1000, True)
    print("rest", O.iter, unbalancedForce(), kineticEnergy(), flush=True)
    if unbalancedForce() < 1e-6:
        break
newton.dead = True                                 # one more step: forces at the positions written
O.run(1, True)
exec(open(os.path.join(here, "export_clumps.py")).read())
export_clumps(os.path.join(out, "bodies.csv"), os.path.join(out, "members.csv"), os.path.join(out, "contacts.csv"),
              gravity=newton.gravity)
