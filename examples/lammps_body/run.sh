#!/usr/bin/env bash
# Run the LAMMPS rounded-polygon example with Debian's LAMMPS (apt-get install -y lammps) into DIR (default: this
# folder): atoms.dump, vertices.dump (64 bodies, one timestep). About 10 s on one core. Then:
#   granstab convert DIR/atoms.dump DIR/vertices.dump data.polygons in.polygons2d --out polygons.json
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
mkdir -p "$out"
cd "$out"
lmp -in "$here/in.polygons2d" -var data "$here/data.polygons" -log none -echo none > lammps.screen 2>&1 || {
  grep -a -m1 -A2 "ERROR" lammps.screen >&2 || tail -20 lammps.screen >&2; exit 1; }
