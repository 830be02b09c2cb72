#!/usr/bin/env bash
# Run the two DEM examples with Debian's LAMMPS (apt-get install -y lammps) and write their dumps into DIR
# (default: this folder): atoms2d.dump contacts2d.dump (1000 disks), atoms3d.dump contacts3d.dump (1000 spheres),
# atoms3d_rolling.dump contacts3d_rolling.dump (the same spheres with rolling resistance), atoms_shear2d.dump
# contacts_shear2d.dump (160 disks sheared in a triclinic periodic box, fix deform xy erate).
# About 5 s each on one core. Then, e.g.:
#   granstab convert DIR/atoms2d.dump DIR/contacts2d.dump in.disks2d --timestep 18000 --out disks.json
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
mkdir -p "$out"
cd "$out"
for script in in.disks2d in.spheres3d in.spheres3d_rolling in.shear2d_periodic; do
  lmp -in "$here/$script" -log none -screen none
done
