"""How tests/data/rigidlibrary_annulus10_frame1_pebbles.json was made: RigidLibrary's own (3,3) pebble game on
DataAnnulus/10 frame 1 with its two boundary bodies. RigidLibrary is GPL-3.0 and not vendored: run this in a
checkout of github.com/silkehenkes/RigidLibrary (commit ca1b63a):

    python3 rigidlibrary_reference.py ../shared/data/rigidlibrary/DataAnnulus/10 1 0.3 > out.json

rigidlibrary_annulus10_heldout_pebbles.json: the same run on frames 5, 12 and 20, each output then kept compact
(free pebbles, failed bars, contact count, each cluster's contacts as "p q"; see `compact`).
"""
import contextlib
import io
import json
import sys

import Pebbles as PB
from Configuration import ConfigurationExpAnnulus

folder, frame, mu = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
conf = object.__new__(ConfigurationExpAnnulus)   # its __init__ passes a string to the base class (fails at HEAD)
settings = {"params": {"folder": folder}, "folder": folder, "experiment": True, "periodic": False,
            "addBoundarySquare": False, "addBoundaryAnnulus": False, "setup": "experiment_annulus", "mu": mu,
            "R1": 1548, "R2": 2995, "mid_x": 3134, "mid_y": 3028, "texture": 30}
for key, value in settings.items():
    setattr(conf, key, value)
with contextlib.redirect_stdout(io.StringIO()):
    conf.ReadData("/particle_positions.txt", "/Adjacency_list.txt", frame)
    conf.AddBoundaryContacts()
    peb = PB.Pebbles(conf, 3, 3, "nothing", False)
    peb.play_game()
    peb.rigid_cluster()
names = [str(int(i)) for i in conf.id[:-2]] + ["inner_wall", "outer_wall"]
con = [[names[int(conf.I[k])], names[int(conf.J[k])], int(peb.cluster[k]), int(conf.fullmobi[k])]
       for k in range(conf.ncon)]


def compact(full: dict) -> dict:
    """One frame's entry of the held-out file: the clusters as lists of "p q", contacts in none left out."""
    clusters = {}
    for a, b, label, _ in full["contacts"]:
        if label >= 0:
            clusters.setdefault(label, []).append(f"{a} {b}")
    return {"free_pebbles": full["free_pebbles"], "failed_bars": full["failed_bars"],
            "contacts": len(full["contacts"]), "clusters": [clusters[k] for k in sorted(clusters)]}


print(json.dumps({"free_pebbles": int(peb.freepeb), "failed_bars": int(peb.fail), "contacts": con}))
