"""Write data.polygons: 64 rounded polygons (squares, pentagons and hexagons of circumradius 1, rounding diameter
0.4, random orientations, mass 1) on a loose 8 x 8 lattice in a periodic 2D box, for in.polygons2d (LAMMPS
atom_style body rounded/polygon; Debian's lammps). Deterministic (seed 7).

    python3 make_data.py [OUT]          (default: data.polygons beside this script)
"""
import math
import random
import sys
from pathlib import Path

random.seed(7)
n_side, spacing, radius, rounding = 8, 3.2, 1.0, 0.4
box = n_side * spacing
lines = ["LAMMPS data file: rounded polygons for granstab (examples/lammps_body/make_data.py)", "",
         f"{n_side * n_side} atoms", f"{n_side * n_side} bodies", "1 atom types", "",
         f"0 {box} xlo xhi", f"0 {box} ylo yhi", "-0.5 0.5 zlo zhi", "", "Atoms", ""]
bodies = ["", "Bodies", ""]
for k in range(n_side * n_side):
    i, j = divmod(k, n_side)
    n = (4, 5, 6)[k % 3]
    lines.append(f"{k + 1} 1 1 1 {(i + 0.5) * spacing} {(j + 0.5) * spacing} 0")
    turn = random.uniform(0, 2 * math.pi)
    izz = radius**2 / 6 * (1 + 2 * math.cos(math.pi / n) ** 2)          # a regular n-gon of unit mass
    bodies += [f"{k + 1} 1 {6 + 3 * n + 1}", str(n), f"{izz / 2!r} {izz / 2!r} {izz!r} 0 0 0"]
    bodies += [f"{radius * math.cos(turn + 2 * math.pi * m / n)!r} {radius * math.sin(turn + 2 * math.pi * m / n)!r} 0"
               for m in range(n)]
    bodies.append(f"{rounding}")
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("data.polygons")
out.write_text("\n".join(lines + bodies) + "\n")
