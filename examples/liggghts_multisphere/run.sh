#!/usr/bin/env bash
# Run a LIGGGHTS multisphere example with Debian's LIGGGHTS (apt-get install -y liggghts) and write its dumps
# into DIR (default: this folder): atoms.dump, contacts.dump, walls.dump, bodies.dump (100 clumps, one timestep).
# SCRIPT (default in.clumps3d: a box of mesh walls; in.periodic: periodic along x and y on a floor).
# About 10 s (in.periodic: 15 s) on one core. Then:
#   granstab convert DIR/atoms.dump DIR/contacts.dump DIR/walls.dump DIR/bodies.dump SCRIPT --out clumps.json
#
#   run.sh [DIR] [SCRIPT]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
script=${2:-in.clumps3d}
mkdir -p "$out"
cp "$here/box.stl" "$here/floor.stl" "$out/"
cd "$out"
stdbuf -o0 -e0 liggghts -in "$here/$script" -log none -echo none > liggghts.screen 2>&1 || {
  grep -a -m1 -A2 "ERROR" liggghts.screen >&2 || tail -20 liggghts.screen >&2; exit 1; }
