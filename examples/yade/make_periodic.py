"""A small frictional packing in a periodic cell made by YADE, exported as granstab's generic tables with the cell
(Debian: apt-get install yade).

    yade -n -x examples/yade/make_periodic.py [OUTDIR]          (a few seconds on one core)

100 spheres (radii 1 : 2 spread, friction angle 30°, Hookean kn from E = 5 MPa) in a periodic cell: compressed
isotropically to 10 kPa by the cell (PeriTriaxController), then sheared (velocity gradient xy: the cell's second
vector tilts along x, a Lees–Edwards-like cell) so that contacts slide. A last step with the integrator off
recomputes every contact at the positions written, then examples/yade/export_granstab.py writes OUTDIR/particles.csv
(with its `# cell:` line) and OUTDIR/contacts.csv, and YADE's own per-body force and torque sums.
"""
import os
import sys

from yade import O, pack
from yade.utils import sphere, unbalancedForce
from yade.wrapper import (Bo1_Sphere_Aabb, ForceResetter, FrictMat, GlobalStiffnessTimeStepper,
                          Ig2_Sphere_Sphere_ScGeom, InsertionSortCollider, InteractionLoop,
                          Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack, NewtonIntegrator,
                          PeriTriaxController)
from yade import Matrix3
from math import radians

here = os.path.dirname(os.path.abspath(sys.argv[0]))     # yade runs the script with argv[0] = its path
out = sys.argv[1] if len(sys.argv) > 1 else here
os.makedirs(out, exist_ok=True)

O.periodic = True
O.cell.hSize = Matrix3(1, 0, 0, 0, 1, 0, 0, 0, 1)
O.materials.append(FrictMat(young=5e6, poisson=0.5, frictionAngle=radians(30), density=2600, label="spheres"))
cloud = pack.SpherePack()
cloud.makeCloud((0, 0, 0), (1, 1, 1), -1, 0.3333, 100, True, 0.95, seed=1)
O.bodies.append([sphere(c, r, material="spheres") for c, r in cloud])

triax = PeriTriaxController(goal=(-1e4, -1e4, -1e4), stressMask=7, maxUnbalanced=0.01, relStressTol=1e-3,
                            maxStrainRate=(0.5, 0.5, 0.5), dynCell=True, mass=0.2)
newton = NewtonIntegrator(damping=0.2)
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb()]),
    InteractionLoop([Ig2_Sphere_Sphere_ScGeom()], [Ip2_FrictMat_FrictMat_FrictPhys()],
                    [Law2_ScGeom_FrictPhys_CundallStrack()]),
    GlobalStiffnessTimeStepper(active=1, timeStepUpdateInterval=100, timestepSafetyCoefficient=0.8),
    triax,
    newton,
]
while O.iter < 40000:                              # isotropic compression to about 10 kPa
    O.run(1000, True)
    print("iso", O.iter, unbalancedForce(), triax.stress, flush=True)
    if unbalancedForce() < 0.05 and abs(triax.stress[0] + 1e4) < 1e3:
        break
triax.dead = True                                  # shear: the cell's velocity gradient, x along y
O.cell.velGrad = Matrix3(0, 0.5, 0, 0, 0, 0, 0, 0, 0)
O.run(int(0.02 / (0.5 * O.dt)), True)              # 2 % shear strain
O.cell.velGrad = Matrix3(0, 0, 0, 0, 0, 0, 0, 0, 0)
print("shear", O.iter, O.cell.hSize, unbalancedForce(), flush=True)
newton.dead = True                                 # one more step: forces at the positions written
O.run(1, True)
exec(open(os.path.join(here, "export_granstab.py")).read())
export_granstab(os.path.join(out, "particles.csv"), os.path.join(out, "contacts.csv"))
export_resultants(os.path.join(out, "yade_resultants.json"),      # YADE's own sums, to check the conversion
                  hSize=[list(O.cell.hSize.row(i)) for i in range(3)])
