"""The model: what a granular cluster is, before any mechanics.

`scene` (particles and contacts as arrays, their checks), `shapes` (disks, ellipses, spheres, ellipsoids →
contact-level data), `surface` (one kernel for smooth surfaces F = 1: superquadrics, their foot points and
parallel-surface curvatures), `law` (the contact law of Sec. 2.6), `tolerances`, `errors` (`SceneError` and value checks),
`vec` (cross products as batched matrices), `packings` (lattice and random packings for tests and benchmarks).
Imports numpy and scipy only.
"""
