"""Local stability scan of whole packings (the paper's Sec. 5): clusters, a parallel runner and the map.

    granstab.scan.extract(scene, "17", rings=1)      # the cluster of particle 17 as a scene of its own
    granstab.scan.scan(scene, "out/", rings=1)       # every cluster → out/clusters.parquet, particles.parquet, ...
    granstab.scan.read_map("out/")                   # {"clusters", "particles", "summary"}

Needs the `scan` extra (pyarrow; dask.distributed for more than one worker; matplotlib for the figures).
"""
from .clusters import extract, members, subscene
from .output import read_map
from .run import scan

__all__ = ["extract", "members", "read_map", "scan", "subscene"]
