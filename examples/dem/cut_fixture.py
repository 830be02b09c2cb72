"""Cut the small reader fixtures in tests/data/io/lammps/ from this folder's dumps (run.sh first): the atoms in a
corner of the periodic cell that wraps around both boundaries, and the local-dump rows among them (neighbour pairs
that do not touch included), at two timesteps (the rolling-resistance run: the last one).  python examples/dem/cut_fixture.py"""
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
OUT = HERE.parents[1] / "tests" / "data" / "io" / "lammps"


def blocks(path):
    text = path.read_text()
    return ["ITEM: TIMESTEP" + b for b in text.split("ITEM: TIMESTEP")[1:]]


def keep_atoms(block, box):
    head, rows = block.split("\n", 9)[:9], block.split("\n", 9)[9].strip().splitlines()
    data = np.array([r.split() for r in rows], float)
    lo, hi = box
    x = data[:, 2:2 + len(lo)]
    inside = np.all(((x >= np.array(lo)) | (x <= np.array(hi))), axis=1)
    return data[inside, 0].astype(int), head, [r for r, k in zip(rows, inside) if k]


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    for tag, steps, box in (("2d", (18000, 21000), ((30.0, 30.0), (6.0, 6.0))),
                            ("3d", (12000, 14000), ((9.0, 9.0, 9.0), (2.5, 2.5, 2.5))),
                            ("3d_rolling", (14000,), ((9.0, 9.0, 9.0), (2.5, 2.5, 2.5)))):
        atoms_out, local_out = [], []
        for ablock, cblock in zip(blocks(HERE / f"atoms{tag}.dump"), blocks(HERE / f"contacts{tag}.dump")):
            if int(ablock.split("\n")[1]) not in steps:
                continue
            ids, head, rows = keep_atoms(ablock, box)
            head[3] = str(len(rows))
            atoms_out += head + rows
            chead, crows = cblock.split("\n", 9)[:9], cblock.split("\n", 9)[9].strip().splitlines()
            pairs = np.array([r.split()[:2] for r in crows], int)
            inside = np.isin(pairs, ids).all(axis=1)
            chead[3] = str(int(inside.sum()))
            local_out += chead + [r for r, k in zip(crows, inside) if k]
        (OUT / f"atoms{tag}.dump").write_text("\n".join(atoms_out) + "\n")
        (OUT / f"contacts{tag}.dump").write_text("\n".join(local_out) + "\n")


if __name__ == "__main__":
    main()
