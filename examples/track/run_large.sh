#!/usr/bin/env bash
# The larger sequences of docs/track-results.md (issue 39), with Debian's LAMMPS, into DIR (default runs-large/):
#   DIR/2d-mu0.1/, DIR/2d-mu0.5/: in.shear2d_track at 2,000 disks, 200 frames, friction mu = 0.1 and 0.5
#   DIR/3d-mu0.5/: in.shear3d_track at 2,000 spheres, 200 frames
# Each folder holds its own copy of the input script with its mu (granstab's LAMMPS reader takes mu from the
# script's `variable mu` line), the dumps and LAMMPS's pressure file. Sizes and frames can be overridden:
#   N=2000 FRAMES=200 bash run_large.sh DIR [2d-mu0.1 2d-mu0.5 3d-mu0.5]
# Then, per folder (docs/track-results.md):
#   granstab track DIR/2d-mu0.5/atoms_shear2d_track.dump DIR/2d-mu0.5/contacts_shear2d_track.dump \
#       DIR/2d-mu0.5/in.shear2d_track --out track-2d-mu0.5/ --predict --workers 1
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-runs-large}
shift || true
runs=("$@")
[ ${#runs[@]} -gt 0 ] || runs=(2d-mu0.1 2d-mu0.5 3d-mu0.5)
n=${N:-2000}
frames=${FRAMES:-200}
for run in "${runs[@]}"; do
  dim=${run%%-*}
  mu=${run#*-mu}
  script=in.shear${dim}_track
  mkdir -p "$out/$run"
  sed "s/^variable        mu equal .*/variable        mu equal ${mu}/" "$here/$script" > "$out/$run/$script"
  (cd "$out/$run" && nice -n 10 lmp -in "$script" -log log.lammps -screen none -var n "$n" -var frames "$frames")
done
