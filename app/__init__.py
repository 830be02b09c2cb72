"""granstab explorer: a viser app to drag particles, set curvature, force and friction, and watch the verdict,
the λ⁽⁶⁾ field and the eigenmodes change live.

Modules, one job each:
  params.py   the sliders' quantities (ranges, steps, labels) — plain data
  scenes.py   scene models: the slider-driven two-particle pair, shape-based clusters, fixed contact-level scenes
  modes.py    labels (rigid, rolling, gear, shearing, sliding, indentation) and animation poses of eigenmodes
  field.py    the λ⁽⁶⁾ field of the symmetric pair over (ρ/r, f/(kr)), and its PNG
  scanmap.py  a scan folder: the packing coloured by its map, the cluster of a clicked particle
  trackmap.py a tracked folder (granstab track): a frame at a time as its scan map, the D²min overlay, the series
  trackview.py  its D²min tick box and the λ_min(t)/stress(t) plot (viser)
  state.py    the per-client session: parameters, poses, current Scene, last analysis, errors (no viser)
  paths.py    what a typed path may open: loopback, --data-root confinement, folders (no viser)
  views.py    drawing in the viser scene (particles, contacts, arrows, osculating circles, surface, animation)
  protocols.py  SceneModel / MapModel: what the explorer asks of a scene model (base classes)
  pools.py    where an analysis runs (this thread, or the server's worker pool shared by every tab)
  readings.py what a session reads from its analysis: the report (once per revision), modes, exports (no viser)
  meshes.py   drawing geometry (outlines, meshes, osculating circles); cellview.py, fieldview.py: parts of views.py
  text.py     the page's HTML and Markdown as pure functions (no viser); figures.py the contour and spectrum
  camera.py   where the camera looks from (the explorer's and the published page's)
  dispatch.py one tab's concurrency rules: the lock, echoes, coalesced sliders, typing pauses, the message line
  panel/      one module per panel (scene, verdict, display, export, modes, field): build(gui), write(session)
  panels.py   the tab: builds the panels and writes them all (refresh)
  server.py   ViserServer wiring, one session per browser tab (memory handed back when it closes), `granstab-app`
  headless.py a page without a browser (viser's websocket protocol): the memory tests and benchmarks
"""
