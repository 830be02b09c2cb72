"""granstab explorer: a viser app to drag particles, set curvature, force and friction, and watch the verdict,
the λ⁽⁶⁾ field and the eigenmodes change live.

Modules, one job each:
  params.py   the sliders' quantities (ranges, steps, labels) — plain data
  models.py   scene models: the slider-driven two-particle pair, shape-based clusters, fixed contact-level scenes
  modes.py    labels (rigid, rolling, gear, shearing, sliding, indentation) and animation poses of eigenmodes
  field.py    the λ⁽⁶⁾ field of the symmetric pair over (ρ/r, f/(kr)), and its PNG
  scanmap.py  a scan folder: the packing coloured by its map, the cluster of a clicked particle
  trackmap.py a tracked folder (granstab track): a frame at a time as its scan map, the D²min overlay, the series
  trackview.py  its D²min tick box and the λ_min(t)/stress(t) plot (viser)
  state.py    the per-client session: parameters, poses, current Scene, last analysis, errors (no viser)
  paths.py    what a typed path may open: loopback, --data-root confinement, folders (no viser)
  views.py    drawing in the viser scene (particles, contacts, arrows, osculating circles, surface, animation)
  panels.py   GUI folders and their callbacks: read handles, call state, write handles
  server.py   ViserServer wiring, one session per browser tab (memory handed back when it closes), `granstab-app`
  headless.py a page without a browser (viser's websocket protocol): the memory tests and benchmarks
"""
