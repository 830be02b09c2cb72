"""granstab explorer: a viser app to drag particles, set curvature, force and friction, and watch the verdict,
the λ⁽⁶⁾ field and the eigenmodes change live.

Modules, one job each:
  params.py   the sliders' quantities (ranges, steps, labels) — plain data
  models.py   scene models: the slider-driven two-particle pair, shape-based clusters, fixed contact-level scenes
  modes.py    labels (rigid, rolling, gear, shearing, sliding, indentation) and animation poses of eigenmodes
  field.py    the λ⁽⁶⁾ field of the symmetric pair over (ρ/r, f/(kr)), and its PNG
  state.py    the per-client session: parameters, poses, current Scene, last analysis, errors (no viser)
  paths.py    what a typed path may open: loopback, --data-root confinement, folders (no viser)
  views.py    drawing in the viser scene (particles, contacts, arrows, osculating circles, surface, animation)
  panels.py   GUI folders and their callbacks: read handles, call state, write handles
  server.py   ViserServer wiring, one session per browser tab (memory handed back when it closes), `granstab-app`
  headless.py a page without a browser (viser's websocket protocol): the memory tests and benchmarks
"""
