"""The explorer's panels, one module each: a class with `build(gui)` (its handles and callbacks, built once) and
`write(session)` (its handles from the session). Callbacks go through the tab's dispatcher (app/dispatch.py,
`ui.run`) and end in `ui.refresh`, which writes every panel (app/panels.py)."""
