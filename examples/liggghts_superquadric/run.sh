#!/bin/sh
# Run the superquadric inputs with the binary build.sh made and copy the dumps into tests/data (the test data).
#   sh run.sh [BINARY]     (default /tmp/liggghts-sq-build/liggghts-sq)
# in.settle takes about a minute on one core (measured 2026-11-29, 40 s of CPU), in.load (which includes it) two,
# in.periodic 20 s, in.rotated a second. in.load_spheres runs with Debian's liggghts: liggghts -in in.load_spheres (copied by hand).
set -eu
BIN=${1:-/tmp/liggghts-sq-build/liggghts-sq}
HERE=$(cd "$(dirname "$0")" && pwd)
DATA="$HERE/../../tests/data/liggghts_superquadric"
WORK=$(mktemp -d)
cp "$HERE"/in.settle "$HERE"/in.rotated "$HERE"/in.load "$HERE"/in.periodic "$WORK"
cd "$WORK"
"$BIN" -in in.rotated > rotated.log
"$BIN" -in in.settle > settle.log
"$BIN" -in in.load > load.log
"$BIN" -in in.periodic > periodic.log
mkdir -p "$DATA"
cp post/atoms.dump post/contacts.dump post/rotated.dump in.settle "$DATA"
mkdir -p "$DATA/load"
cp post/load_atoms.dump "$DATA/load/atoms.dump"
cp post/load_contacts.dump "$DATA/load/contacts.dump"
mkdir -p "$DATA/periodic"
cp post/periodic_atoms.dump "$DATA/periodic/atoms.dump"
cp post/periodic_contacts.dump "$DATA/periodic/contacts.dump"
cp in.periodic "$DATA/periodic"
echo "wrote $DATA"
