#!/usr/bin/env bash
# Run the LIGGGHTS example with Debian's LIGGGHTS (apt-get install -y liggghts) and write its dumps into DIR
# (default: this folder): atoms.dump, contacts.dump (200 spheres, one timestep). About 1 s on one core. Then:
#   granstab convert DIR/atoms.dump DIR/contacts.dump in.spheres3d --out spheres.json
# LIGGGHTS stops through MPI_Abort on an input error: stdout is unbuffered here (stdbuf) so that the ERROR line
# before the abort reaches the screen or the log instead of being lost in the buffer.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here}
mkdir -p "$out"
cd "$out"
stdbuf -o0 -e0 liggghts -in "$here/in.spheres3d" -log none -echo none > liggghts.screen 2>&1 || {
  grep -a -m1 -A2 "ERROR" liggghts.screen >&2 || tail -20 liggghts.screen >&2; exit 1; }
