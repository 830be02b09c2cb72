"""Local stability scan of whole packings (the paper's Sec. 5): clusters, a parallel runner and the map.

    granstab.scan.extract(scene, "17", rings=1)      # the cluster of particle 17 as a scene of its own
    granstab.scan.scan(scene, "out/", rings=1)       # every cluster → out/clusters.parquet, particles.parquet, ...
    granstab.scan.read_map("out/")                   # {"clusters", "particles", "summary"}; centres and members
    granstab.scan.read_packing("out/")               # are indices into the packing the folder keeps (packing.npz)

Needs the `scan` extra (pyarrow; dask.distributed for more than one worker; matplotlib for the figures).
"""
from .clusters import cluster, extract, members, subscene
from .output import open_packing, read_map, read_packing
from .run import scan

__all__ = ["cluster", "extract", "members", "open_packing", "read_map", "read_packing", "scan", "subscene"]
