#!/usr/bin/env bash
# Run the two `granstab track` sequences with Debian's LAMMPS (apt-get install -y lammps) into DIR (default: this
# folder): atoms_shear2d_track.dump contacts_shear2d_track.dump pressure_shear2d.txt (200 disks, 40 frames) and
# atoms_shear3d_track.dump contacts_shear3d_track.dump pressure_shear3d.txt (300 spheres, 40 frames); about
# 5 and 10 s on one core. Extra arguments go to both runs, e.g. the larger 2D run of docs/track-results.md:
#   bash run.sh big -var n 2000 -var frames 200
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
shift || true
mkdir -p "$out"
cd "$out"
for script in in.shear2d_track in.shear3d_track; do
  lmp -in "$here/$script" -log none -screen none "$@"
done
