#!/usr/bin/env bash
# Run the LIGGGHTS multisphere example with Debian's LIGGGHTS (apt-get install -y liggghts) and write its dumps
# into DIR (default: this folder): atoms.dump, contacts.dump, walls.dump, bodies.dump (100 clumps, one timestep).
# About 10 s on one core. Then:
#   granstab convert DIR/atoms.dump DIR/contacts.dump DIR/walls.dump DIR/bodies.dump in.clumps3d --out clumps.json
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
mkdir -p "$out"
cp "$here/box.stl" "$out/box.stl"
cd "$out"
stdbuf -o0 -e0 liggghts -in "$here/in.clumps3d" -log none -echo none > liggghts.screen 2>&1 || {
  grep -a -m1 -A2 "ERROR" liggghts.screen >&2 || tail -20 liggghts.screen >&2; exit 1; }
