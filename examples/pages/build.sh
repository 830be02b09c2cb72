#!/usr/bin/env bash
# The teaching pages of docs/tour.md's steps: each one self-contained HTML file written by `granstab publish` (it opens
# offline in a browser, no Python; 0.8-1.4 MB each, of which 0.8 MB is viser's client). Every one is tracked in git
# (tests/house/test_house.py allows them up to issue 29's 5 MB a page); this script writes them again here:
#     bash examples/pages/build.sh
set -euo pipefail
cd "$(dirname "$0")"
for preset in two_particle ellipses_sharp four_disk gear_packing gear_packing_rolling spheres_tetrahedron \
              annulus_frame; do
    python -m granstab publish "$preset" --out "$preset.html"
done
