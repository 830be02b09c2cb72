#!/bin/sh
# Run the superquadric inputs with the binary build.sh made and copy the dumps into tests/data (the test data).
#   sh run.sh [BINARY]     (default /tmp/liggghts-sq-build/liggghts-sq)
# in.settle takes about 10 minutes on one core; in.rotated a second.
set -eu
BIN=${1:-/tmp/liggghts-sq-build/liggghts-sq}
HERE=$(cd "$(dirname "$0")" && pwd)
DATA="$HERE/../../tests/data/liggghts_superquadric"
WORK=$(mktemp -d)
cp "$HERE"/in.settle "$HERE"/in.rotated "$WORK"
cd "$WORK"
"$BIN" -in in.rotated > rotated.log
"$BIN" -in in.settle > settle.log
mkdir -p "$DATA"
cp post/atoms.dump post/contacts.dump post/rotated.dump in.settle "$DATA"
echo "wrote $DATA"
